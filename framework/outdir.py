"""An output folder (`--out DIR`) locked while a run writes it.

Two runs writing one folder (or a `--resume` of a live run's folder) would interleave their checkpoints
and tables; the second is refused with one line (InputError, exit 2) naming the live run's pid.

The lock is the operating system's advisory lock (`fcntl.flock`; `msvcrt.locking` on Windows) held on
DIR/.crashlab.lock for the whole run. The kernel releases it when its process ends however it ends, kill -9
included, so a killed run never leaves a lock that blocks: no pid is guessed alive or dead, a reused pid
cannot keep a folder locked. The file holds the holder's pid, command and start time, for the refusal's
message; a run that finds the file written but unlocked (its writer was killed) takes it over with a note
on stderr. A run that ends normally removes the file. (The `filelock` package locks the same way on Unix
through flock, but is no dependency of crashlab and says nothing about the previous holder.)

The lock is re-entrant within a process: a command that locks DIR and calls a function that locks it
again (Study.run with out_dir) holds it once.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import os
import sys
from pathlib import Path

from .errors import InputError

LOCK_NAME = ".crashlab.lock"


def check_output_file(path, key: str) -> Path:
    """A file a command will write (--plot, --animate, --csv FILE), checked before the run: no folder, and the
    nearest folder on its path that exists a folder (missing ones are made when it is written); otherwise, or for a
    name the system refuses (longer than 255 bytes), InputError naming the path and `key`."""
    path = Path(path)
    try:
        if path.is_dir():
            raise InputError(str(path), key, "a folder; give a file name")
        folder = next((p for p in path.parents if p.exists()), None)
    except OSError as err:
        raise InputError(str(path), key, f"cannot write there ({err.strerror or err})") from None
    if folder is not None and not folder.is_dir():
        raise InputError(str(path), key, f"cannot write there: {folder} is not a folder")
    return path


_HELD: dict[str, list] = {}  # real path of a locked folder -> [fd, depth] (this process)

try:
    import fcntl

    def _try_lock(fd: int) -> bool:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            return False

    def _unlock(fd: int) -> None:
        fcntl.flock(fd, fcntl.LOCK_UN)
except ImportError:  # Windows
    import msvcrt

    def _try_lock(fd: int) -> bool:
        os.lseek(fd, 0, os.SEEK_SET)
        try:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
            return True
        except OSError:
            return False

    def _unlock(fd: int) -> None:
        os.lseek(fd, 0, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)


def _read(fd: int) -> str:
    os.lseek(fd, 0, os.SEEK_SET)
    return os.read(fd, 4096).decode("utf-8", "replace").strip()


def _holder(text: str) -> str:
    """'pid N, crashlab COMMAND, started T' from the lock file's line (pid, command, start time)."""
    parts = text.split("\t")
    if len(parts) == 3:
        return f"pid {parts[0]}, crashlab {parts[1]}, started {parts[2]}"
    return "its pid unknown"


def _open_locked(lock: Path, out_dir: Path) -> tuple[int, str]:
    """(fd holding the lock on `lock`, the previous holder's line or ""); InputError when a live run holds it."""
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            raise InputError(out_dir, "--out", f"cannot create {LOCK_NAME}: {err.strerror or err}") from None
        if not _try_lock(fd):
            holder = _read(fd)
            os.close(fd)
            raise InputError(out_dir, "--out", f"another crashlab run is writing this folder ({_holder(holder)}); "
                             "wait for it to end, or give another --out")
        try:  # the file may have been removed by the holder's release between our open and our lock
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            return fd, _read(fd)
        _unlock(fd)
        os.close(fd)


@contextlib.contextmanager
def lock_out_dir(out_dir, command: str = "run"):
    """Hold DIR's lock for the body (module docstring); DIR is created if missing (and removed again if the
    body left it empty). `out_dir` None: no lock. InputError (--out) when a live run holds it."""
    if out_dir is None:
        yield None
        return
    out_dir = Path(out_dir)
    created = not out_dir.exists()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(out_dir, "--out", err.strerror or str(err)) from None
    key = os.path.realpath(out_dir)
    if key in _HELD:  # this process holds it already
        _HELD[key][1] += 1
        try:
            yield out_dir
        finally:
            _HELD[key][1] -= 1
        return
    lock = out_dir / LOCK_NAME
    fd, previous = _open_locked(lock, out_dir)
    if previous:
        print(f"crashlab: note: {out_dir}: the run that locked it ({_holder(previous)}) ended without releasing "
              "it (killed?); its lock is taken over", file=sys.stderr)
    start = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    os.ftruncate(fd, 0)
    os.lseek(fd, 0, os.SEEK_SET)
    os.write(fd, f"{os.getpid()}\t{command}\t{start}\n".encode())
    os.fsync(fd)
    _HELD[key] = [fd, 1]
    try:
        yield out_dir
    finally:
        del _HELD[key]
        with contextlib.suppress(OSError):
            lock.unlink()  # before the unlock: a run waiting on this file sees it gone and opens a new one
        _unlock(fd)
        os.close(fd)
        if created:
            with contextlib.suppress(OSError):
                out_dir.rmdir()  # only when empty: a run refused before it wrote anything leaves no folder
