"""Regenerate ``wooddecay/samples/tree_skeleton.toml``: a dead tree with three branch orders.

Deterministic (fixed seed). Trunk 4.5 m tall tapering from 0.14 m to 0.05 m radius with a slight
lean; five first-order branches (golden-angle azimuths, rising at about 40 degrees); two
second-order branches on each. Run: ``python scripts/make_tree_skeleton.py``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parent.parent / "wooddecay" / "samples" / "tree_skeleton.toml"


def main() -> None:
    rng = np.random.default_rng(2026)
    nodes: list[tuple[str, np.ndarray, str | None, float]] = []

    def chain(prefix, start, parent, direction, length, r0, r1, n, wobble):
        ids, pos, d = [], start.copy(), direction / np.linalg.norm(direction)
        for k in range(1, n + 1):
            d = d + rng.normal(0.0, wobble, 3)
            d /= np.linalg.norm(d)
            pos = pos + d * (length / n)
            nid = f"{prefix}{k}"
            nodes.append((nid, pos.copy(), parent, r0 + (r1 - r0) * k / n))
            ids.append((nid, pos.copy(), d.copy()))
            parent = nid
        return ids

    nodes.append(("t0", np.zeros(3), None, 0.14))
    trunk = chain("t", np.zeros(3), "t0", np.array([0.03, 0.0, 1.0]), 4.5, 0.14, 0.05, 9, 0.03)
    golden = np.pi * (3.0 - np.sqrt(5.0))
    for b, k in enumerate((2, 3, 4, 5, 6)):
        tid, tpos, _ = trunk[k]
        az = b * golden
        d = np.array([np.cos(az), np.sin(az), 0.85])
        r0 = 0.055 - 0.006 * b
        br = chain(f"b{b}_", tpos, tid, d, 1.5 - 0.15 * b, r0, 0.018, 4, 0.08)
        for c, j in enumerate((1, 2)):
            bid, bpos, bdir = br[j]
            side = np.cross(bdir, [0.0, 0.0, 1.0])
            side = side / np.linalg.norm(side) * (1 if c == 0 else -1)
            chain(f"b{b}_{c}_", bpos, bid, bdir + 1.2 * side + [0, 0, 0.3], 0.55, 0.024, 0.012, 2, 0.1)

    lines = ["# Dead tree skeleton written by scripts/make_tree_skeleton.py (do not edit by hand).\n"]
    for nid, pos, parent, radius in nodes:
        lines.append("\n[[node]]\n")
        lines.append(f'id = "{nid}"\n')
        lines.append("position = [%.4f, %.4f, %.4f]\n" % tuple(pos))
        if parent is not None:
            lines.append(f'parent = "{parent}"\n')
        if nid == "t0":
            lines.append("anchored = true\n")
        lines.append(f'profile = {{ kind = "circle", radius = {radius:.4f} }}\n')
    OUT.write_text("".join(lines), encoding="utf-8")
    print(f"wrote {OUT} ({len(nodes)} nodes)")


if __name__ == "__main__":
    main()
