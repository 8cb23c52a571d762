"""Building and installing the Blender add-on (``wooddecay/blender_addon/``, shipped in the wheel).

``wooddecay addon build`` makes the installable extension zip in plain Python (:func:`build`): the
zip Blender's own builder (``blender --command extension build``) writes, without needing
Blender or the ``bpy`` wheel, so it works from an installed wheel: ``blender_manifest.toml`` and
the add-on's files at the top of ``<id>-<version>.zip``, the files chosen by the manifest's
``[build] paths_exclude_pattern`` (gitignore-style patterns, as Blender reads them). It checks
the manifest's required fields; Blender's builder validates more strictly (tags included): the
tests build the zip with both and compare them (:func:`blender_build`, :func:`validate`).

Blender's extension tools are ``bl_pkg.bl_extension_cli`` (with ``bl_pkg/cli/blender_ext.py``),
which the ``bpy`` wheel ships under ``bpy/<version>/scripts/addons_core/bl_pkg``.
:func:`install` runs their ``extension install-file`` (used by the renders and the tests; Blender
users install the zip from Blender itself).

Everything that imports ``bpy`` runs in a subprocess of this Python: ``bpy`` bundles its own
``pxr``, which must never meet usd-core's ``pxr`` in one interpreter (docs/architecture.md "Blender add-on").
"""
from __future__ import annotations

import fnmatch
import importlib.metadata
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

from .atomic import cache_home, tree_hash

#: the add-on's source folder: package data of wooddecay (in a checkout and in an installed wheel)
SOURCE = Path(__file__).resolve().parent / "blender_addon"
MANIFEST = "blender_manifest.toml"
#: the manifest fields Blender requires (schema 1.0.0)
REQUIRED = ("schema_version", "id", "version", "name", "tagline", "maintainer", "type", "blender_version_min",
            "license")
#: Blender's ``paths_exclude_pattern`` when the manifest has no ``[build]`` table
DEFAULT_EXCLUDE = ("__pycache__/", ".*", "/*.zip")
#: files Blender's builder stores without compressing (archives and wheels)
STORED = (".whl", ".bz2", ".gz", ".lz4", ".lzma", ".rar", ".xz", ".zip", ".zst", ".tbz2", ".tgz", ".txz", ".tzst")

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
        raise AddonError(f"{path}: no Blender extension manifest (the add-on's files are missing from "
                         "this wooddecay install)")
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as err:
        raise AddonError(f"{path}: {err}") from None


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


def manifest_errors(m: dict) -> list[str]:
    """What is wrong with the manifest ``m`` for Blender's builder: the checks it makes on the
    required fields, the id, the type, the tagline and the license (not the tags)."""
    errors = [f"missing required field {key!r}" for key in REQUIRED if key not in m]
    strings = [k for k in REQUIRED if k in m and k != "license" and not (isinstance(m[k], str) and m[k].strip())]
    errors += [f"field {key!r}: a non-empty string expected" for key in strings]
    if isinstance(m.get("id"), str) and m["id"] and "id" not in strings:
        idname = m["id"]
        if not idname.isidentifier() or "__" in idname or idname.startswith("_") or idname.endswith("_"):
            errors.append(f"field 'id': {idname!r} is not a valid identifier (single '_' separators, none at the ends)")
    if m.get("type", "add-on") not in ("add-on", "theme"):
        errors.append(f"field 'type': 'add-on' or 'theme' expected, found {m['type']!r}")
    tagline = m.get("tagline")
    if isinstance(tagline, str) and tagline and "tagline" not in strings:
        if len(tagline) > 64:
            errors.append(f"field 'tagline': at most 64 characters, found {len(tagline)}")
        if not (tagline[-1].isalnum() or tagline[-1] in ")]}"):
            errors.append("field 'tagline': must not end with punctuation")
    if "license" in m:
        lic = m["license"]
        if not (isinstance(lic, list) and lic and all(isinstance(x, str) and x.startswith("SPDX:") for x in lic)):
            errors.append("field 'license': a non-empty list of \"SPDX:<identifier>\" strings expected")
    if "generated" in m.get("build", {}):
        errors.append("the source manifest must not have [build.generated] (it is written by builds)")
    return errors


def _excluded(parts: tuple[str, ...], is_dir: bool, patterns) -> bool:
    """Whether the path ``parts`` (relative to the add-on's folder) matches one of the gitignore-style
    ``patterns`` as Blender's builder reads them: ``/`` at the start anchors at the folder, ``/``
    at the end matches only folders, ``*`` and ``?`` stay within one name."""
    for pattern in patterns:
        anchored, dir_only = pattern.startswith("/"), pattern.endswith("/")
        names = pattern.strip("/").split("/")
        if dir_only and not is_dir or len(names) > len(parts):
            continue
        start = len(parts) - len(names)
        if anchored and start:
            continue
        if all(fnmatch.fnmatchcase(part, name) for part, name in zip(parts[start:], names)):
            return True
    return False


def files(source: Path = SOURCE) -> list[tuple[Path, str]]:
    """(path, name in the zip) of each file the extension zip of ``source`` holds, the manifest
    first, then the files not excluded by ``[build] paths_exclude_pattern`` in path order
    (symbolic links left out, as Blender does)."""
    source = Path(source).resolve()
    m = manifest(source)
    build_table = m.get("build")
    if build_table is None:
        patterns = list(DEFAULT_EXCLUDE)
    else:
        if "paths" in build_table or m.get("wheels"):
            raise AddonError(f"{source / MANIFEST}: [build] paths and wheels are not supported by "
                             "wooddecay's builder; build with Blender's (blender --command extension build)")
        patterns = list(build_table.get("paths_exclude_pattern", []))
    bad = [p for p in patterns if not isinstance(p, str) or p.startswith("!") or "**" in p]
    if bad:
        raise AddonError(f"{source / MANIFEST}: paths_exclude_pattern {bad!r}: negation and '**' are not "
                         "supported by wooddecay's builder")
    found = [(source / MANIFEST, MANIFEST)]

    def walk(folder: Path, parts: tuple[str, ...]) -> None:
        for entry in sorted(os.scandir(folder), key=lambda e: e.name):
            if entry.is_symlink():
                continue
            rel, is_dir = (*parts, entry.name), entry.is_dir()
            if _excluded(rel, is_dir, patterns):
                continue
            if is_dir:
                walk(Path(entry.path), rel)
            elif entry.is_file() and rel != (MANIFEST,):
                found.append((Path(entry.path), "/".join(rel)))

    walk(source, ())
    return found


def build(output_dir, source: Path = SOURCE) -> Path:
    """Build the extension zip of ``source`` into ``output_dir`` (created if missing) as Blender's
    ``extension build`` does, without Blender; returns the zip's path. Written beside it under a
    dot name and renamed into place."""
    source = Path(source).resolve()
    m = manifest(source)
    errors = manifest_errors(m)
    if errors:
        raise AddonError(f"{source / MANIFEST}: " + "; ".join(errors))
    entries = files(source)
    if m["type"] == "add-on" and not any(name.startswith("__init__.") for _, name in entries):
        raise AddonError(f"{source}: not a Python package (no __init__.py)")
    out = Path(output_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    path = out / zip_name(source)
    tmp = out / f".{path.name}"
    try:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as z:
            for file, name in entries:
                z.write(file, name, compress_type=zipfile.ZIP_STORED if name.lower().endswith(STORED) else None)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def blender_build(output_dir, source: Path = SOURCE, timeout: float | None = 600.0) -> Path:
    """Build the extension zip of ``source`` into ``output_dir`` with Blender's own
    ``extension build`` (needs the bpy wheel; validates the manifest strictly, tags included);
    returns the zip's path. The tests compare it with :func:`build`'s."""
    source = Path(source).resolve()
    name = zip_name(source)
    out = Path(output_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    extension_command(["build", "--source-dir", source, "--output-dir", out], timeout=timeout)
    path = out / name
    if not path.is_file():
        raise AddonError(f"Blender's extension builder did not write {path}")
    return path


def validate(zip_path, timeout: float | None = 600.0) -> str:
    """Blender's ``extension validate`` of the extension zip ``zip_path`` (needs the bpy wheel);
    its output, or AddonError."""
    return extension_command(["validate", Path(zip_path).resolve()], timeout=timeout)


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
