"""Building and installing the Blender add-on (``blender_addon/``) with Blender's own tools.

``wooddecay addon build`` makes the installable extension zip with Blender's extension builder,
the code behind ``blender --command extension build``: ``bl_pkg.bl_extension_cli`` (with
``bl_pkg/cli/blender_ext.py``), which the ``bpy`` wheel ships under
``bpy/<version>/scripts/addons_core/bl_pkg``. It validates ``blender_manifest.toml`` (strictly,
tags included) and writes ``<id>-<version>.zip``. :func:`install` runs ``extension install-file``
the same way (used by the tests; Blender users install the zip from Blender itself).

Everything that imports ``bpy`` runs in a subprocess of this Python: ``bpy`` bundles its own
``pxr``, which must never meet usd-core's ``pxr`` in one interpreter (docs/architecture.md "Blender add-on").
"""
from __future__ import annotations

import importlib.metadata
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

from .atomic import cache_home, tree_hash

#: the add-on's source folder in a source checkout
SOURCE = Path(__file__).resolve().parent.parent / "blender_addon"
MANIFEST = "blender_manifest.toml"

#: ``blender --command extension ARGS`` with the bpy module: argv[1:] are the ARGS
EXTENSION_CLI = """\
import sys
import bpy  # noqa: F401  (puts Blender's scripts folders on sys.path)
from bl_pkg import bl_extension_cli
sys.stdout.flush()
sys.exit(bl_extension_cli.cli_extension_handler(sys.argv[1:]))
"""


class AddonError(RuntimeError):
    """The add-on could not be built or installed (message says why, in one line or more)."""


def manifest(source: Path = SOURCE) -> dict:
    """The add-on's ``blender_manifest.toml`` as a dict."""
    path = Path(source) / MANIFEST
    if not path.is_file():
        raise AddonError(f"{path}: no Blender extension manifest (is this a source checkout?)")
    with open(path, "rb") as f:
        return tomllib.load(f)


def zip_name(source: Path = SOURCE) -> str:
    """``<id>-<version>.zip``, the name Blender's builder gives the package."""
    m = manifest(source)
    return f"{m['id']}-{m['version']}.zip"


def check_bpy() -> None:
    """AddonError unless the ``bpy`` wheel is installed (checked without importing it)."""
    if importlib.util.find_spec("bpy") is None:
        raise AddonError("the bpy wheel is not installed: pip install 'bpy==4.5.*' (Python 3.11)")


def run_bpy(code: str, args=(), env: dict | None = None, timeout: float | None = 600.0,
            cwd=None) -> subprocess.CompletedProcess:
    """Run ``code`` with ``args`` in a fresh interpreter of this Python (which imports bpy);
    returns the completed process (text output captured)."""
    check_bpy()
    full_env = dict(os.environ) | (env or {})
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], env=full_env, cwd=cwd,
                           capture_output=True, text=True, timeout=timeout)


def extension_command(args, env: dict | None = None, timeout: float | None = 600.0) -> str:
    """``blender --command extension ARGS`` through the bpy wheel; its output, or AddonError."""
    proc = run_bpy(EXTENSION_CLI, args, env=env, timeout=timeout)
    out = (proc.stdout + proc.stderr).strip()
    if proc.returncode != 0:
        raise AddonError(f"Blender's 'extension {args[0]}' failed (exit {proc.returncode}):\n{out}")
    return out


def build(output_dir, source: Path = SOURCE, timeout: float | None = 600.0) -> Path:
    """Build the extension zip of ``source`` into ``output_dir`` (created if missing) with
    Blender's ``extension build``; returns the zip's path."""
    source = Path(source).resolve()
    name = zip_name(source)
    out = Path(output_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    extension_command(["build", "--source-dir", source, "--output-dir", out], timeout=timeout)
    path = out / name
    if not path.is_file():
        raise AddonError(f"Blender's extension builder did not write {path}")
    return path


def install(zip_path, user_resources=None, repo: str = "user_default", enable: bool = True,
            timeout: float | None = 600.0) -> str:
    """``extension install-file`` of ``zip_path`` into ``repo`` (enabled when ``enable``).
    ``user_resources``: a folder to use as Blender's user resources (BLENDER_USER_RESOURCES:
    preferences and extensions), to leave the real user's Blender alone."""
    env = {} if user_resources is None else {"BLENDER_USER_RESOURCES": str(Path(user_resources).resolve())}
    args = ["install-file", "--repo", repo, *(["--enable"] if enable else []), Path(zip_path).resolve()]
    return extension_command(args, env=env, timeout=timeout)


def installed(source: Path = SOURCE) -> Path:
    """Blender user resources (BLENDER_USER_RESOURCES) with the extension of ``source`` built and
    installed, kept in ``$XDG_CACHE_HOME/wooddecay/addon/<key>`` (``~/.cache/...``), the key the
    sha256 of the source's files and the bpy wheel's version. Why: building and installing took
    3.5 s of every render (the gallery renders about 45). Built in a temporary folder beside it
    and renamed into place, so a render running beside it finds a whole one or none."""
    check_bpy()
    source = Path(source).resolve()
    base = cache_home() / "addon"
    folder = base / tree_hash(source, salt=importlib.metadata.version("bpy").encode())[:32]
    if not folder.is_dir():
        base.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=".build-", dir=base))
        try:
            install(build(tmp / "dist", source), user_resources=tmp / "user")
            shutil.rmtree(tmp / "dist")
            os.rename(tmp, folder)
        except OSError:
            if not folder.is_dir():  # not the loser of a race with another render
                raise
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return folder / "user"
