"""The rot preview colour shared by the exporters (USD ``displayColor``, glTF ``COLOR_0``).

A plain viewer shows the decay of woodstock §5 without the Blender material: brown rot (cellulose
lost, low H_c) darkens the wood, white rot (lignin lost, low H_l) bleaches it, moisture M darkens.
"""
from __future__ import annotations

import numpy as np

#: preview colours (linear RGB): sound wood, brown-rot, white-rot
SOUND = np.array([0.62, 0.42, 0.22])
BROWN = np.array([0.22, 0.10, 0.05])
WHITE = np.array([0.85, 0.80, 0.68])


def rot_color(H_c: np.ndarray, H_l: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Preview colour: brown rot (cellulose lost, low H_c) darkens towards BROWN, white rot (lignin
    lost, low H_l) bleaches towards WHITE, moisture darkens by up to 30%."""
    b = np.clip(1.0 - H_c, 0.0, 1.0)[:, None]
    w = np.clip(1.0 - H_l, 0.0, 1.0)[:, None]
    c = SOUND * (1.0 - b) + BROWN * b
    c = c * (1.0 - w) + WHITE * w
    return (c * (1.0 - 0.3 * np.clip(M, 0.0, 1.0))[:, None]).astype(np.float32)
