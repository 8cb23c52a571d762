"""Input errors: one clear line naming the file, the key and what is allowed.

Every boundary (scene TOML, skeleton files, TreeQSM tables, CLI ``--set``) raises
:class:`InputError`; the CLI prints ``str(err)`` on one line and exits with code 2.
"""
from __future__ import annotations


class InputError(ValueError):
    """A user input that cannot be used.

    Parameters
    ----------
    file : str
        The file (or ``<overrides>`` / ``<string>``) the bad value came from.
    key : str
        Dotted key or node id that is wrong, e.g. ``strands.r_s`` or ``skeleton.node[n3]``.
    message : str
        What is wrong and what is allowed, e.g. ``"-1 is outside (0, 1] m"``.
    """

    def __init__(self, file: str, key: str, message: str):
        self.file = str(file)
        self.key = str(key)
        self.message = str(message)
        super().__init__(str(self))

    def __str__(self) -> str:  # one line, always
        text = f"{self.file}: {self.key}: {self.message}" if self.key else f"{self.file}: {self.message}"
        return " ".join(text.split())
