"""Regenerate the tree skeletons: ``wooddecay/samples/tree_skeleton.toml`` and the two other trees of
the gallery's Fig. 19 (``wooddecay/samples/gallery/``). Each is a dead tree with three branch orders.

Deterministic (fixed seeds). The sample: a trunk 4.5 m tall tapering from 0.14 m to 0.05 m radius
with a slight lean; five first-order branches (golden-angle azimuths, rising at about 40 degrees);
two second-order branches on each. The spruce-like tree is taller and slimmer with seven short,
nearly level branches; the birch-like tree is low with four long, steep branches.
Run: ``python scripts/make_tree_skeleton.py``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

SAMPLES = Path(__file__).resolve().parent.parent / "wooddecay" / "samples"
#: file: (seed, height, trunk radius at base and top, first-order branches (one per trunk node
#: upwards), trunk node of the lowest one, branch length, rise of a branch (z per unit horizontal), branch base radius)
TREES = {
    SAMPLES / "tree_skeleton.toml": (2026, 4.5, 0.14, 0.05, 5, 2, 1.5, 0.85, 0.055),
    SAMPLES / "gallery" / "fig19_spruce_skeleton.toml": (7, 5.5, 0.13, 0.04, 7, 2, 0.9, 0.2, 0.04),
    SAMPLES / "gallery" / "fig19_birch_skeleton.toml": (19, 3.2, 0.12, 0.06, 4, 3, 1.8, 1.4, 0.055),
}


def tree(seed, height, r_base, r_top, n_branches, first, length, rise, r_branch):
    """Nodes (id, position, parent, radius) of one tree (the TREES parameters)."""
    rng = np.random.default_rng(seed)
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

    nodes.append(("t0", np.zeros(3), None, r_base))
    trunk = chain("t", np.zeros(3), "t0", np.array([0.03, 0.0, 1.0]), height, r_base, r_top, 9, 0.03)
    golden = np.pi * (3.0 - np.sqrt(5.0))
    for b in range(n_branches):
        tid, tpos, _ = trunk[first + b]
        az = b * golden
        d = np.array([np.cos(az), np.sin(az), rise])
        r0 = r_branch - 0.006 * b * 5 / max(n_branches, 5)
        br = chain(f"b{b}_", tpos, tid, d, length * (1.0 - 0.1 * b * 5 / max(n_branches, 5)), r0, 0.018, 4, 0.08)
        for c, j in enumerate((1, 2)):
            bid, bpos, bdir = br[j]
            side = np.cross(bdir, [0.0, 0.0, 1.0])
            side = side / np.linalg.norm(side) * (1 if c == 0 else -1)
            chain(f"b{b}_{c}_", bpos, bid, bdir + 1.2 * side + [0, 0, 0.3], 0.55, 0.024, 0.012, 2, 0.1)

    return nodes


def write(path: Path, nodes) -> None:
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
    path.write_text("".join(lines), encoding="utf-8")
    print(f"wrote {path} ({len(nodes)} nodes)")


def main() -> None:
    for path, params in TREES.items():
        write(path, tree(*params))


if __name__ == "__main__":
    main()
