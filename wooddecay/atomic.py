"""Atomic file output: never a half file (docs/architecture.md "CLI": outputs are written to a temporary name
and renamed).

:func:`write_bytes` writes to a hidden temporary file in the target's folder that keeps the real
suffix last (USD picks its format from it), flushes it to disk and renames it over the target;
:func:`replace_with` runs any writer on such a temporary path. A failure raises
:class:`~wooddecay.errors.InputError` naming the file, and removes the temporary file.
:func:`check_output` validates an output path before any work is done. :func:`read_archive` reads
back an ``.npz`` of arrays and a JSON ``meta`` (checkpoints, the settled-state cache).
:func:`cache_home` is wooddecay's folder in the user's cache (the settled states, the add-on), and
:func:`tree_hash` the key of what is cached from a folder of files (the add-on's source, the package's code).
"""
from __future__ import annotations

import hashlib
import json
import os
import pickle
import zipfile
from pathlib import Path

import numpy as np

from .errors import InputError


def check_output(path, suffixes: tuple[str, ...], what: str) -> Path:
    """``path`` as a Path after checking its suffix and that its folder exists."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise InputError(str(path), "", f"a {what} file must end in {', '.join(suffixes)}")
    if not path.parent.is_dir():
        raise InputError(str(path), "", f"folder {path.parent} does not exist")
    return path


def replace_with(path, write, what: str) -> Path:
    """Call ``write(tmp)`` for a temporary path next to ``path``, then rename it over ``path``."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        write(tmp)
        os.replace(tmp, path)
    except Exception as err:
        if isinstance(err, InputError):
            raise
        raise InputError(str(path), "", f"cannot write the {what} file: {err}") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def write_bytes(path, data: bytes, what: str = "output") -> Path:
    """Write ``data`` to ``path`` atomically (flushed to disk before the rename)."""
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    return replace_with(path, write, what)


def read_archive(path) -> tuple[dict, dict]:
    """(meta, arrays) of the ``.npz`` at ``path``: its JSON ``meta`` object and its other arrays;
    ValueError naming the file when it is not such an archive (missing, damaged, truncated)."""
    try:
        with np.load(path) as z:
            meta = json.loads(str(z["meta"]))
            arrays = {k: z[k].copy() for k in z.files if k != "meta"}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, pickle.UnpicklingError) as err:
        raise ValueError(f"{path}: not a readable archive ({type(err).__name__})") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: not a readable archive (its meta is no object)")
    return meta, arrays


def cache_home() -> Path:
    """``$XDG_CACHE_HOME/wooddecay`` (``~/.cache/wooddecay`` without the variable)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "wooddecay"


def tree_hash(root: Path, pattern: str = "*", salt: bytes = b"") -> str:
    """SHA-256 of ``salt`` and the files under ``root`` whose names match ``pattern`` (outside
    ``__pycache__``), each as its path relative to ``root`` and its bytes, in path order."""
    digest = hashlib.sha256(salt)
    for path in sorted(p for p in root.rglob(pattern) if p.is_file() and "__pycache__" not in p.parts):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()
