"""The one lock of an output folder: every writer of a sequence, run, map, bench or sweep folder holds it.

Two processes writing one folder mixed their files (two renders of different seeds left
``sequence.json`` of one seed beside frames of the other; two sweeps into one folder both
exited 0 with the rows of one). So every writer takes :func:`lock_folder` on the folder it
writes, for as long as it writes, and a second writer is refused in one line naming the
folder and the holder's pid (:class:`~floorvo.errors.FolderLockedError`, exit code 1 in
the CLIs). Readers never lock.

The lock is ``fcntl.flock`` on ``FOLDER/.floorbench.lock`` (:data:`LOCK_FILE`), a file that
holds the holder's ``PID HOST``. The operating system drops a ``flock`` when its process
ends in any way, SIGKILL included, so a killed writer never leaves a folder locked. Its
lock file may stay behind; the next writer takes it over, and removes the temporaries of
atomic writes the killed one left directly in the folder
(:func:`floorvo.io.remove_stale_temporaries`: only a holder of the lock writes there). The
lock file is no file of any format: "is this folder ours" checks and ``--overwrite``
ignore it. A writer that releases its lock, or whose interpreter exits normally, removes it.

Granularity and nesting: a lock covers one folder, not its subfolders. A writer that writes
inside another's folder takes its own lock (the bench holds its output folder, each
sequence it renders and each run folder it writes; a sweep's main process holds the sweep
folder, its workers each sequence and run folder of their jobs), so nested writers never
wait for each other. Within one thread the lock is re-entrant: a writer that calls another
writer of the same folder (``run_estimator`` then ``RunFolder.write``) takes it again
without waiting, and the lock ends when the outermost holder releases it. Another thread
of the same process is refused like another process (``flock`` locks are per open file).

A fork()ed child does not inherit the locks of its parent (they are closed in the child).
Where ``fcntl`` does not exist (Windows) nothing is locked; a warning says so once.
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import functools
import inspect
import logging
import os
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, TypeVar, cast

from floorvo.errors import FloorbenchError, FolderLockedError
from floorvo.io import checked_output_path, remove_stale_temporaries, sequence_folder_above

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

__all__ = ["LOCK_FILE", "FolderLock", "lock_folder", "locks_folder", "lock_holder", "signals_deferred"]

log = logging.getLogger(__name__)

#: The lock file inside a locked folder (not a format file: readers and ``--overwrite`` ignore it).
LOCK_FILE = ".floorbench.lock"
#: How often a waiting writer tries again (s).
_WAIT_STEP_S = 0.1


@dataclass
class _Held:
    """A lock this process holds: the open lock file and the folders taking it created, deepest first."""

    fd: int
    folder: Path  # absolute: a later chdir must not move the lock file released
    key: tuple[str, int]
    created: list[Path]


#: The locks this process holds, by (real path of the folder, thread id).
_held: dict[tuple[str, int], _Held] = {}
_registry = threading.Lock()


class FolderLock:
    """A held folder lock (from :func:`lock_folder`). ``release()`` (or the end of a ``with``
    block) gives it back; releasing twice does nothing. A ``with`` block left by a
    :class:`~floorvo.errors.FloorbenchError` (the writer refused its input, or another writer
    holds a folder it needs) also removes the folders that taking the lock created, while
    they are empty: a refused command leaves no empty output folder behind. ``outer``: this holder took the lock
    from the operating system; the lock ends when it releases it (a re-entrant holder's
    release does nothing, so an inner writer that is released late, by the garbage
    collector, never keeps the folder locked after its outer writer ended)."""

    def __init__(self, held: _Held, outer: bool):
        self._held: _Held | None = held
        self.outer = outer
        self.folder = held.folder  # absolute

    def release(self, *, refused: bool = False) -> None:
        """Give the lock back; ``refused``: the writer was refused, remove the empty folders it created."""
        held, self._held = self._held, None
        if held is not None and self.outer:
            _release(held, refused)

    @property
    def held(self) -> bool:
        return self._held is not None

    def __enter__(self) -> FolderLock:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.release(refused=isinstance(exc, FloorbenchError))


#: The file that marks a folder as one kind of output, and the kind (:func:`lock_folder`'s ``what``)
#: that alone may write there (a run folder's ``result.json``: :data:`floorvo.runfolder.RESULT`).
_KIND_MARKERS = (("sequence.json", "sequence folder"), ("map.json", "map folder"), ("result.json", "run folder"))


def _other_kind_problem(path: Path, what: str) -> str:
    """Why a ``what`` may not be written into folder ``path`` ('' when it may): the folder is
    another kind's (:data:`_KIND_MARKERS`), or lies inside a sequence folder. ``floorvo run SEQ
    -o SEQ`` wrote its run into the sequence, ``-o SEQ/cam0`` among its frames, ``floorvo map SEQ
    -o RUN`` a map among a run's files and ``floorvo localize SEQ --map MAP -o MAP`` a run among
    the map's. A plain ``folder`` (a lock taken for a file written into a folder) is anything's."""
    if what == "folder":
        return ""
    for marker, kind in _KIND_MARKERS:
        if what != kind and (path / marker).is_file():
            return f"{path}: is a {kind} ({marker}); a {what} goes in a folder of its own"
    seq = sequence_folder_above(path)
    if seq is not None:
        return f"{path}: inside the sequence folder {seq} (sequence.json); a {what} goes in a folder of its own"
    return ""


def lock_folder(folder: str | os.PathLike, what: str = "folder", *, wait: bool = False) -> FolderLock:
    """Lock the output folder ``folder`` (created with its parents) for this writer; returns the lock.

    Use it as ``with lock_folder(out, "run folder"):`` or keep the returned :class:`FolderLock`
    and ``release()`` it. ``what`` names the folder in the refusal (``sequence folder``).
    When another process, or another thread of this one, holds it: ``wait=False`` raises
    :class:`~floorvo.errors.FolderLockedError` ("FOLDER: another writer (pid N) is writing
    this WHAT; ..."); ``wait=True`` waits until it is free (a render cache shared by several
    benches: the second waits for the first's render, then reuses it). The same thread may
    take a lock it holds again (re-entrant; the lock ends when its first holder releases it). A path that exists and is not a folder is a
    one-line :class:`~floorvo.errors.FloorbenchError`, and so is a folder that cannot be
    created or written, a sequence, map or run folder locked as another kind (a run, map or
    bench written into a sequence, a map into a run folder), and any folder inside a sequence
    folder (:func:`_other_kind_problem`); a plain ``folder`` is refused none of these.
    """
    path = checked_output_path(folder, FloorbenchError)  # no lock file in the current folder ("") or in "/"
    problem = _other_kind_problem(path, what)
    if problem:
        raise FloorbenchError(problem)
    waited = False
    while True:
        created = _make_folder(path)
        key = (os.path.realpath(path), threading.get_ident())
        with _registry:
            held = _held.get(key)
            if held is not None:
                return FolderLock(held, outer=False)
        with signals_deferred():  # an interrupt here left the lock file of a lock nobody held
            fd = _try_lock(path / LOCK_FILE)
            if isinstance(fd, int):
                held = _Held(fd, Path(os.path.abspath(path)), key, created)
                with _registry:
                    _held[key] = held  # from here on released at exit whatever happens
        if fd is None:  # the folder vanished between mkdir and open (its last holder removed it): again
            continue
        if isinstance(fd, str):  # the holder, as the lock file names it
            if not wait:
                raise _refusal(path, what, fd)
            if not waited:
                log.info("%s: waiting for %s to finish writing it", path, _describe_holder(fd))
                waited = True
            time.sleep(_WAIT_STEP_S)
            continue
        assert held is not None  # fd is ours: recorded above
        # Only a holder of this lock writes here: a temporary in the folder is a killed writer's.
        for stale in remove_stale_temporaries(path):
            log.info("%s: removed the temporary of a writer that was killed", stale)
        return FolderLock(held, outer=True)


F = TypeVar("F", bound=Callable[..., Any])


def locks_folder(param: str, what: str) -> Callable[[F], F]:
    """Decorator: the function holds :func:`lock_folder` on its argument ``param`` (a folder it
    writes) for as long as it runs. ``what`` names the folder in a refusal (``run folder``).

    ``@locks_folder("out_dir", "run folder")`` on ``run_estimator(seq, name, out_dir, ...)``.
    """

    def decorate(fn: F) -> F:
        signature = inspect.signature(fn)

        @functools.wraps(fn)
        def locked(*args: Any, **kwargs: Any) -> Any:
            bound = signature.bind(*args, **kwargs)
            bound.apply_defaults()
            with lock_folder(bound.arguments[param], what):
                return fn(*args, **kwargs)

        return cast(F, locked)

    return decorate


def lock_holder(folder: str | os.PathLike) -> str | None:
    """``"PID HOST"`` of the writer holding ``folder``'s lock now, or None when no one holds it
    (a lock file a killed writer left behind is not held). Reads only; takes nothing."""
    lock_path = Path(folder) / LOCK_FILE
    try:
        fd = os.open(lock_path, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return None
    try:
        if fcntl is None:  # pragma: no cover - Windows
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                return _read_holder(fd)
            raise
        return None
    finally:
        os.close(fd)


# ----------------------------------------------------------------------------- the parts
def _make_folder(path: Path) -> list[Path]:
    """Create ``path`` and its missing parents; returns the folders this call created, deepest first."""
    if path.exists() and not path.is_dir():
        raise FloorbenchError(f"{path}: output path exists and is not a folder")
    missing = []
    p = Path(os.path.abspath(path))
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    try:
        path.mkdir(parents=True)
    except FileExistsError:
        if not path.is_dir():
            raise FloorbenchError(f"{path}: output path exists and is not a folder") from None
        return []
    except OSError as exc:  # a parent that is a file, a read-only parent
        raise _not_writable(path, exc) from None
    return missing


def _not_writable(path: Path, exc: OSError) -> FloorbenchError:
    return FloorbenchError(f"{path}: output folder is not writable ({exc.strerror or exc})")


def _try_lock(lock_path: Path) -> int | str | None:
    """Take the lock file's ``flock``: the open descriptor when taken, the holder's ``PID HOST``
    when another holds it, None when the folder is gone (try again)."""
    while True:
        try:
            fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
        except FileNotFoundError:
            return None
        except OSError as exc:  # a read-only folder
            raise _not_writable(lock_path.parent, exc) from None
        try:
            if fcntl is not None:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            else:  # pragma: no cover - Windows
                _warn_unlocked()
        except OSError as exc:
            holder = _read_holder(fd)
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                return holder
            raise
        # The holder before us may have removed the file after we opened it: our lock is then
        # on a file nobody else sees. Only a lock on the file at the path counts.
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(lock_path))
        except FileNotFoundError:
            same = False
        if same:
            _write_holder(fd)
            return fd
        os.close(fd)


_warned: list[bool] = []


def _warn_unlocked() -> None:  # pragma: no cover - Windows
    if not _warned:
        _warned.append(True)
        log.warning("no fcntl on this system: output folders are not locked against a second writer")


def _write_holder(fd: int) -> None:
    """Write ``PID HOST`` into the lock file (best effort: a full disk must not stop the writer
    that holds the lock; a refusal then says the pid is unknown)."""
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()} {socket.gethostname()}\n".encode(), 0)
    except OSError as exc:
        log.debug("lock file: cannot record the pid (%s)", exc)


def _read_holder(fd: int) -> str:
    """The lock file's ``PID HOST`` ("" when unreadable). The holder writes it just after taking
    the lock, so a read in between may find it empty or a killed holder's: read again briefly."""
    text = ""
    for _ in range(20):
        try:
            text = os.pread(fd, 200, 0).decode("utf-8", "replace").strip()
        except OSError:
            return ""
        pid, host = _parse_holder(text)
        if pid is not None and (host != socket.gethostname() or _alive(pid)):
            return text
        time.sleep(0.01)
    return text


def _parse_holder(text: str) -> tuple[int | None, str]:
    parts = text.split()
    try:
        pid = int(parts[0]) if parts else None
    except ValueError:
        pid = None
    return pid, parts[1] if len(parts) > 1 else ""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _describe_holder(holder: str) -> str:
    pid, host = _parse_holder(holder)
    if pid is None:
        return "another writer (pid unknown)"
    if host and host != socket.gethostname():
        return f"another writer (pid {pid} on {host})"
    if pid == os.getpid():
        return f"another thread of this process (pid {pid})"
    return f"another writer (pid {pid})"


def _refusal(path: Path, what: str, holder: str) -> FolderLockedError:
    pid, _ = _parse_holder(holder)
    return FolderLockedError(
        f"{path}: {_describe_holder(holder)} is writing this {what}; "
        "wait for it to finish or choose another output folder",
        str(path),
        pid,
    )


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """SIGINT and SIGTERM held back (their handlers run when the block ends) while a lock is taken
    or given back: a Ctrl-C between creating the lock file and recording the lock, or between
    forgetting it and removing the file, left a ``.floorbench.lock`` that no exit clean-up removed.
    The block never waits (the lock is tried with ``LOCK_NB``). The renderer imports Mitsuba in
    such a block too (:func:`floorsim.render._import_mitsuba`): an interrupt inside Dr.Jit's
    import became an ordinary exception there, and the render went on, crashed, or exited 0.

    Python runs signal handlers, and so raises ``KeyboardInterrupt``, in the main thread only: there
    the handlers are swapped for one that notes the signal (blocking the signal with
    ``pthread_sigmask`` does not do: another thread of the process may take it). A signal with its
    default action (SIGTERM outside a CLI command) ends the process as it would have."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[tuple[int, Any]] = []
    previous: dict[int, Callable[[int, Any], Any]] = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(sig)
        if callable(handler):
            previous[sig] = handler
            signal.signal(sig, lambda signum, frame: caught.append((signum, frame)))
    try:
        yield
    finally:
        for restored, handler in previous.items():
            signal.signal(restored, handler)
        for signum, frame in caught:
            previous[signum](signum, frame)


def _release(held: _Held, refused: bool) -> None:
    with signals_deferred():
        with _registry:
            _held.pop(held.key, None)
        # Remove the lock file while still holding the lock (a writer that opened it meanwhile
        # finds it gone and takes a new one), then give the lock up.
        try:
            os.unlink(held.folder / LOCK_FILE)
        except OSError:
            pass
        os.close(held.fd)
    for folder in held.created if refused else ():  # a refused writer leaves no empty folders behind
        try:
            folder.rmdir()
        except OSError:
            break


def _forget_after_fork() -> None:
    """In a fork()ed child: close the inherited lock files and forget the parent's locks (the
    child is not their writer; the parent keeps them)."""
    global _registry
    _registry = threading.Lock()  # another thread may have held it at the fork
    for held in _held.values():
        try:
            os.close(held.fd)
        except OSError:
            pass
    _held.clear()


def _release_all_at_exit() -> None:
    """At a normal interpreter exit, give back (and remove the files of) the locks still held."""
    for held in list(_held.values()):
        _release(held, refused=False)


atexit.register(_release_all_at_exit)
if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_after_fork)
