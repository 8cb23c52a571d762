"""``python -m wooddecay``: the ``wooddecay`` command, for environments without its script on PATH
(a Blender or DCC Python, a batch worker)."""
import sys

from .cli import main

sys.exit(main(prog_name="wooddecay"))
