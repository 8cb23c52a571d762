"""Render a wooddecay bake with the Wood Decay add-on's material to a PNG with Blender's ``bpy``:
runs ``wooddecay/render/blender_bake.py`` (its docstring lists the options), e.g.

    python scripts/render_bake.py /tmp/log_bake/log.usdc docs/images/log-late.png --frame 23
"""
import os
import runpy

runpy.run_path(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "wooddecay", "render", "blender_bake.py"),
               run_name="__main__")
