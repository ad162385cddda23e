"""floorvo: odometry for downward-looking floor cameras.

Never imports Mitsuba, so it runs on real data. Layers:

* data model: :mod:`floorvo.camera`, :mod:`floorvo.tum`, :mod:`floorvo.sequence`;
* primitives every estimator and the mapping share: :mod:`floorvo.geometry` (transforms,
  the rigid fit, pixel <-> floor conversions), :mod:`floorvo.matching` (descriptor
  matchers), :mod:`floorvo.imaging` (LED falloff correction);
* configuration: :mod:`floorvo.config` (typed frozen dataclasses, one ``--set`` parser);
* estimators: :mod:`floorvo.estimators` (one protocol, a registry by name); the keyframe
  map and relocalisation: :mod:`floorvo.mapping`;
* runs: :mod:`floorvo.runner` (the one frame loop), :mod:`floorvo.runfolder` (the one
  writer and reader of ``RUN/trajectory.txt``, ``timing.csv``, ``result.json``);
* metrics: :mod:`floorvo.metrics`;
* CLI: :mod:`floorvo.cli` (thin calls to the functions above).

Units: millimetres and radians in code; TUM files in metres and seconds.
"""

__version__ = "0.1.0"

from floorvo.errors import FloorbenchError  # noqa: E402

__all__ = ["FloorbenchError", "__version__"]
