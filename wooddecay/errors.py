"""Input errors: one clear line naming the file, the key and what is allowed.

Every boundary (scene TOML, skeleton files, TreeQSM tables, CLI ``--set``) raises
:class:`InputError`; the CLI prints ``str(err)`` on one line and exits with code 2 (docs/model.md §1).
:func:`type_name`, :func:`format_value` and :func:`did_you_mean` are the words those messages
share: a value's TOML type, a short rendering of the value, and the closest allowed name.
"""
from __future__ import annotations

import difflib
import math
import numbers
from typing import Any, Iterable


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

    def __reduce__(self):  # pickled with its three parts (a bake in another process raises it)
        return type(self), (self.file, self.key, self.message)

    def __str__(self) -> str:  # one line, always
        text = f"{self.file}: {self.key}: {self.message}" if self.key else f"{self.file}: {self.message}"
        return " ".join(text.split())


def type_name(v: Any) -> str:
    """TOML-flavoured name of a value's type for messages."""
    if isinstance(v, bool):
        return "boolean"
    if isinstance(v, numbers.Integral):
        return "integer"
    if isinstance(v, numbers.Real):
        return "float"
    if isinstance(v, str):
        return "string"
    if isinstance(v, dict):
        return "table"
    if isinstance(v, (list, tuple)):
        return "array"
    return type(v).__name__


def format_value(v: Any, limit: int = 60) -> str:
    """Short, one-line, TOML-like rendering of a value for messages."""
    if isinstance(v, bool):
        s = "true" if v else "false"
    elif isinstance(v, numbers.Integral):
        try:
            s = str(int(v))
        except ValueError:  # more digits than Python converts to text
            s = f"<integer of about {int(int(v).bit_length() * math.log10(2)) + 1} digits>"
        if len(s) > 30 and s[0] != "<":
            s = f"{s[:12]}...({len(s)} digits)"
    elif isinstance(v, numbers.Real):
        f = float(v)
        s = "nan" if math.isnan(f) else ("inf" if f == math.inf else ("-inf" if f == -math.inf else repr(f)))
    elif isinstance(v, str):
        s = repr(v)
    else:
        try:
            s = repr(v)
        except Exception:  # pragma: no cover - defensive
            s = f"<{type(v).__name__}>"
    s = " ".join(s.split())
    if len(s) > limit:
        s = s[: limit - 3] + "..."
    return s


def did_you_mean(word: Any, candidates: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest candidate, or ``""``."""
    cands = [str(c) for c in candidates]
    w = str(word)
    lower = {c.lower(): c for c in cands}
    match = None
    if w.lower() in lower and lower[w.lower()] != w:
        match = lower[w.lower()]
    else:
        close = difflib.get_close_matches(w, cands, n=1, cutoff=0.6)
        if close:
            match = close[0]
    return f"; did you mean {match!r}?" if match else ""
