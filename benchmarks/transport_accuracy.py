"""Transport accuracy on the irregular rod graph (docs/model.md §7), printed as ``name value unit``:
heat-kernel variance growth over 2 D a_dir and Fisher-KPP front speed over 2 sqrt(alpha D_dir),
along e_l, e_r and e_t (1.0 is exact), with the seconds each took; then the resolution q of the
decay fronts of ``SCENE`` (default samples/log.toml; every shipped sample has its strands and
rods) and the front speed on the rod graph (with the fronts' correction, sim/fronts.py) and on a
1D lattice without it at each of those q, in biology steps of ALPHA_DT / alpha.

    python benchmarks/transport_accuracy.py [SCENE]
"""
from __future__ import annotations

import sys
import time

from wooddecay.model import build_model
from wooddecay.scene import load_scene
from wooddecay.sim.fronts import lattice_speed_ratio
from wooddecay.studies.transport import fisher_speed_ratio, front_resolution, heat_kernel_ratio

for direction in ("l", "r", "t"):
    t0 = time.perf_counter()
    ratio, clamps = heat_kernel_ratio(direction)
    print(f"heat_kernel_ratio_{direction} {ratio:.4f} - (clamps {clamps}, {time.perf_counter() - t0:.1f} s)")
for direction in ("l", "r", "t"):
    t0 = time.perf_counter()
    ratio, clamps = fisher_speed_ratio(direction)
    print(f"fisher_speed_ratio_{direction} {ratio:.4f} - (clamps {clamps}, {time.perf_counter() - t0:.1f} s)")
#: alpha dt of the shipped samples' biology substeps: 0.017 (log), 0.008 (fig14), 0.004 (tree) for white rot
ALPHA_DT = 0.01
scene = sys.argv[1] if len(sys.argv) > 1 else "samples/log.toml"
for fungus, qs in front_resolution(build_model(load_scene(scene))).items():
    for direction, q in qs.items():
        ratio, clamps = fisher_speed_ratio(direction, q=q, alpha_dt=ALPHA_DT)
        print(f"front_q_{fungus}_{direction} {q:.2f} - (rod graph {ratio:.4f}, 1D lattice {lattice_speed_ratio(q, ALPHA_DT):.4f}, "
              f"clamps {clamps})")
