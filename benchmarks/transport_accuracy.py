"""Transport accuracy on the irregular rod graph (SPEC §7), printed as ``name value unit``:
heat-kernel variance growth over 2 D a_dir and Fisher-KPP front speed over 2 sqrt(alpha D_dir),
along e_l, e_r and e_t (1.0 is exact), with the seconds each took."""
from __future__ import annotations

import time

from wooddecay.studies.transport import fisher_speed_ratio, heat_kernel_ratio

for direction in ("l", "r", "t"):
    t0 = time.perf_counter()
    ratio, clamps = heat_kernel_ratio(direction)
    print(f"heat_kernel_ratio_{direction} {ratio:.4f} - (clamps {clamps}, {time.perf_counter() - t0:.1f} s)")
for direction in ("l", "r", "t"):
    t0 = time.perf_counter()
    ratio, clamps = fisher_speed_ratio(direction)
    print(f"fisher_speed_ratio_{direction} {ratio:.4f} - (clamps {clamps}, {time.perf_counter() - t0:.1f} s)")
