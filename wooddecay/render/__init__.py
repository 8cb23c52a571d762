"""Renders of bakes through the Blender add-on, from Python.

``blender_bake.py`` and ``blender_common.py`` in this folder run inside ``bpy`` (the wheel, or a
Blender binary with ``-b -P``); ``bpy`` bundles its own ``pxr``, which must never meet usd-core's,
so wooddecay never imports them: :func:`render_bake` runs ``blender_bake.py`` in a subprocess of
this Python. ``bpy`` is the ``render`` extra (``pip install "wooddecay[render]"``).
"""
from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

#: the render script (its docstring: options and picture)
BLENDER_BAKE = Path(__file__).with_name("blender_bake.py")


def available() -> bool:
    """Whether the ``bpy`` wheel is installed (without importing it)."""
    return importlib.util.find_spec("bpy") is not None


def render_bake(usd, png, frame: int | None = None, options=()) -> str:
    """Render the bake ``usd`` at ``frame`` (default: its last) into ``png`` with the add-on's
    material; ``options``: more of ``blender_bake.py``'s arguments. Returns what the script
    printed; raises RuntimeError with its last lines if it fails."""
    from ..addon import installed

    cmd = [sys.executable, str(BLENDER_BAKE), str(usd), str(png), *map(str, options)]
    if frame is not None:
        cmd += ["--frame", str(frame)]
    env = dict(os.environ, WOODDECAY_ADDON_USER=str(installed()))  # built once, not per render
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False, env=env)
    if proc.returncode != 0:
        tail = (proc.stdout + proc.stderr).strip().splitlines()[-3:]
        raise RuntimeError(f"rendering {usd} failed: {' / '.join(tail)}")
    return proc.stdout
