"""All-or-nothing file writes: stage every file under a temporary name, then rename; a write that
fails (a full disk, no permission) is a one-line error naming the file."""

from __future__ import annotations

import errno
import fcntl
import os
import secrets
import stat
import time
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO

from trials.errors import DiskFullError, StudyError

#: The mode of a file only its owner may read (a blinded study's sealed files).
PRIVATE_FILE = 0o600
#: errno values that mean the file system has no room left (for anyone, or for this user).
NO_SPACE = (errno.ENOSPC, errno.EDQUOT)


@contextmanager
def no_space(path: Path) -> Iterator[None]:
    """Turn running out of space while writing `path` into a DiskFullError naming it."""
    try:
        yield
    except OSError as exc:
        if exc.errno in NO_SPACE:
            raise DiskFullError(f"no space left on the device to write {path}; free some and run the command again") from None
        raise


def os_error_text(exc: OSError) -> str:
    """What the file system refused, in one line naming the file (both, for a move): for the error a command ends with."""
    where = " -> ".join(os.fsdecode(name) for name in (exc.filename, exc.filename2) if name is not None)
    if exc.errno in NO_SPACE:
        return f"no space left on the device{' to write ' + where if where else ''}; free some and run the command again"
    return f"{where}: {exc.strerror}" if where and exc.strerror else str(exc)


@contextmanager
def writing(path: Path) -> Iterator[None]:
    """Turn an OSError while writing `path` into an error naming it: DiskFullError when there is no space."""
    try:
        with no_space(path):
            yield
    except OSError as exc:
        raise StudyError(f"cannot write {path}: {exc.strerror or exc}") from None


def open_lock(path: Path, mode: str) -> IO[str]:
    """A lock file opened as `mode` ("r": it must exist; "a" or "a+": made when absent), refused in one line when it is not
    a regular file: opening a FIFO would wait for a writer or reader forever, and a link could point anywhere.

    Raises:
        FileNotFoundError: mode "r" and no file.
        StudyError: a FIFO, a device, a folder or a symbolic link in its place.
    """
    flags = {"r": os.O_RDONLY, "a": os.O_WRONLY | os.O_CREAT | os.O_APPEND, "a+": os.O_RDWR | os.O_CREAT | os.O_APPEND}[mode]
    refused = f"{path} is not a regular file (a FIFO, device, folder or link in its place): remove it and run the command again"
    try:
        fd = os.open(path, flags | os.O_NONBLOCK | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        if exc.errno in (errno.ENXIO, errno.ELOOP, errno.EISDIR):
            raise StudyError(refused) from None
        if mode == "r":
            raise
        with writing(path):  # a read-only folder or a full disk: an error naming the lock file
            raise
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise StudyError(refused)
    return os.fdopen(fd, mode, encoding="utf-8")


#: Seconds a writer waits for another process's read-change-write of the same file before it gives up.
LOCK_WAIT_S = 30.0


@contextmanager
def one_writer(path: Path, wait_s: float = LOCK_WAIT_S) -> Iterator[None]:
    """Hold `path`'s writer lock (a hidden `.<name>.writing` beside it) for a read-change-write, so that writers in other
    processes (the console, `trials score`, `trials respond`) take turns and no one's rows are lost.

    Raises:
        StudyError: another process held the lock for `wait_s` seconds.
    """
    lock = path.with_name(f".{path.name}.writing")
    with writing(lock):
        lock.parent.mkdir(parents=True, exist_ok=True)
        handle = open_lock(lock, "a")
    deadline = time.monotonic() + wait_s
    try:
        while True:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    raise StudyError(f"another process has been writing {path} for over {wait_s:g} s (it holds {lock}); "
                                     "try again, or stop it") from None
                time.sleep(0.01)
        yield
    finally:
        handle.close()  # closing the file releases the lock


def write_files(files: dict[Path, bytes], private: Collection[Path] = (), before_commit: Callable[[], object] | None = None) -> None:
    """Write several files so that none is left half-written; those in `private` are created 0600.

    Each file is first written and flushed to a temporary name in its own folder; only when
    all are staged are they renamed over their targets, so a failure or an interrupt before
    that point leaves every existing file as it was. `before_commit` runs once everything is staged, just before the
    renames: moving the old files aside there means a full disk or a read-only folder fails before anything moved.
    """
    staged: list[tuple[Path, Path]] = []
    try:
        for target, content in files.items():
            temporary = target.with_name(f".{target.name}.{secrets.token_hex(4)}.tmp")
            with writing(target):
                target.parent.mkdir(parents=True, exist_ok=True)
                mode = PRIVATE_FILE if target in private else 0o666  # 0o666: as open() does, less the umask
                descriptor = os.open(temporary, os.O_CREAT | os.O_EXCL | os.O_WRONLY, mode)
                staged.append((temporary, target))
                with os.fdopen(descriptor, "wb") as handle:
                    handle.write(content)
                    handle.flush()
                    os.fsync(handle.fileno())
        if before_commit is not None:
            before_commit()
        for temporary, target in staged:
            with writing(target):
                os.replace(temporary, target)
    finally:
        for temporary, _ in staged:
            with suppress(OSError):  # the error that got here is the one to report
                temporary.unlink(missing_ok=True)


def write_text(path: Path, text: str) -> None:
    """Write one UTF-8 text file atomically."""
    write_files({path: text.encode("utf-8")})
