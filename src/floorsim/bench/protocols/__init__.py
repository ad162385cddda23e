"""Paper protocols as bench plugins: a registry by name, chosen by what each scene declares.

A scene asks for protocols in its ``[bench]`` table::

    [bench]
    protocols = ["paper000-strip"]

and a scene file without that table gets the protocols whose ``default_for`` holds its
trajectory type (``protocols = []`` turns them off). The built-in protocols, registered
here and nowhere else:

* ``paper000-strip`` (:mod:`.paper000`): paper 000's strip runs, Figs. 8 and 9;
* ``paper001-line`` (:mod:`.paper001`): paper 001's 0.783 % over a 3 m line;
* ``paper003-relocalisation`` (:mod:`.paper003`): paper 003's keyframe map and kidnapping.

Another protocol is a :class:`~floorsim.bench.protocols.base.BenchProtocol` subclass
passed to :func:`register_protocol`.
"""

from __future__ import annotations

from typing import Any

from floorsim.bench.protocols.base import BenchContext, BenchProtocol, ProtocolOutput, SceneRun, trajectory_type
from floorsim.bench.protocols.paper000 import Paper000Strip
from floorsim.bench.protocols.paper001 import Paper001Line
from floorsim.bench.protocols.paper003 import Paper003Relocalisation
from floorvo.errors import ConfigError, shown

__all__ = [
    "PROTOCOLS",
    "BenchContext",
    "BenchProtocol",
    "ProtocolOutput",
    "SceneRun",
    "get_protocol",
    "list_protocols",
    "protocols_for_scene",
    "register_protocol",
]

#: Registered protocols by name, in registration order (the order the bench runs them in).
PROTOCOLS: dict[str, BenchProtocol] = {}


def register_protocol(protocol: BenchProtocol) -> BenchProtocol:
    """Add ``protocol`` (an instance) to :data:`PROTOCOLS` under its ``name``."""
    for attr in ("name", "description"):
        if not getattr(protocol, attr, None):
            raise TypeError(f"bench protocol {type(protocol).__name__} lacks {attr!r}")
    PROTOCOLS[protocol.name] = protocol
    return protocol


def get_protocol(name: str) -> BenchProtocol:
    if name not in PROTOCOLS:
        raise ConfigError(f"bench protocol {name!r}: unknown (known: {', '.join(PROTOCOLS)})")
    return PROTOCOLS[name]


def list_protocols() -> list[str]:
    return list(PROTOCOLS)


def protocols_for_scene(scene: Any) -> list[BenchProtocol]:
    """The protocols ``scene`` (anything with ``to_dict()``) asks for, in registration order.

    ``bench.protocols`` names them; without it, those whose ``default_for`` holds the
    scene's trajectory type. Refuses (:class:`ConfigError`, one line) an unknown name and a
    protocol that does not run on the scene's trajectory type.
    """
    ttype = trajectory_type(scene)
    names = (scene.to_dict().get("bench") or {}).get("protocols")
    if names is None:
        return [p for p in PROTOCOLS.values() if ttype in p.default_for]
    if isinstance(names, str) or not all(isinstance(n, str) for n in names):
        raise ConfigError(f"bench.protocols = {shown(names)}: must be a list of protocol names")
    for n in names:
        if n not in PROTOCOLS:
            raise ConfigError(f"bench.protocols: {shown(n)} is not a bench protocol (known: {', '.join(PROTOCOLS)})")
        p = PROTOCOLS[n]
        if p.trajectory_types and ttype not in p.trajectory_types:
            raise ConfigError(
                f"bench.protocols: {n!r} runs on a trajectory of type {' or '.join(p.trajectory_types)}, not {ttype!r}"
            )
    return [p for p in PROTOCOLS.values() if p.name in names]


for _protocol in (Paper000Strip(), Paper001Line(), Paper003Relocalisation()):
    register_protocol(_protocol)
