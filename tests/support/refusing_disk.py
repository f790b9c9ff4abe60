"""A folder whose file system refuses to be changed, as a read-only mount (EROFS) or a full disk (ENOSPC) refuses it:
every call that would create, write or (read-only only) move or remove something under the folder fails with that
errno, at the same Python calls the kernel's refusal would surface from. Tests run as root ignore file modes, so a
chmod cannot make a folder read-only for them; this does, on any machine."""

from __future__ import annotations

import builtins
import errno
import io
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

#: os.open flags that change a file.
_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_TRUNC


def refuse_changes(monkeypatch: pytest.MonkeyPatch, root: Path, code: int) -> list[str]:
    """From now on, changes under `root` fail with `code` (errno.EROFS or errno.ENOSPC); returns the list that each
    refused path is appended to. A full disk still lets files be renamed and removed; a read-only folder does not."""
    base = os.path.abspath(root)
    refused: list[str] = []

    def inside(path: Any) -> bool:
        if isinstance(path, int):
            return False
        where = os.path.abspath(os.fsdecode(path))
        return where == base or where.startswith(base + os.sep)

    def refuse(path: Any) -> None:
        refused.append(os.fsdecode(path))
        raise OSError(code, os.strerror(code), os.fsdecode(path))

    def guard(original: Callable[..., Any], changes: Callable[..., bool] = lambda *a, **k: True) -> Callable[..., Any]:
        def guarded(path: Any, *args: Any, **kwargs: Any) -> Any:
            if inside(path) and changes(*args, **kwargs):
                refuse(path)
            return original(path, *args, **kwargs)
        return guarded

    def open_writes(mode: str = "r", *args: Any, **kwargs: Any) -> bool:
        return any(c in mode for c in "wax+")

    monkeypatch.setattr(os, "open", guard(os.open, lambda flags, *a, **k: bool(flags & _WRITE_FLAGS)))
    monkeypatch.setattr(builtins, "open", guard(builtins.open, open_writes))
    monkeypatch.setattr(io, "open", guard(io.open, open_writes))
    guarded_mkdir = guard(os.mkdir)

    def mkdir(path: Any, *args: Any, **kwargs: Any) -> None:
        if inside(path) and os.path.lexists(path):  # the kernel answers "exists" before it looks for room or write access
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), os.fsdecode(path))
        guarded_mkdir(path, *args, **kwargs)

    monkeypatch.setattr(os, "mkdir", mkdir)
    if code != errno.ENOSPC:  # a full disk still renames, removes and changes modes
        for name in ("rename", "replace", "unlink", "remove", "rmdir", "chmod", "utime", "truncate"):
            monkeypatch.setattr(os, name, guard(getattr(os, name)))
    return refused
