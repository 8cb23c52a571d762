"""Debris settling (wooddecay.studies.debris; woodstock §5.4, Fig. 12): the tiny log broken
into its BSP blocks falls, piles up and sleeps."""
from __future__ import annotations

import numpy as np
import pytest

from wooddecay.sim import mechanics
from wooddecay.studies import debris

from ..sim.helpers import fragments, sleep_digest

@pytest.mark.slow
def test_debris_settles_asleep_without_interpenetrating():
    """Issue "Debris": the pieces fall 5 cm, pile up and come to rest: within 8 s every piece
    sleeps and stays asleep for 0.5 s (so the largest speed is 0 < 1e-3 m/s), each fell asleep only after its particles
    had moved less than sleep_speed over a whole window, and no two capsules of different pieces
    overlap by more than 0.1 r_s beyond their rest overlap. Resuming from the arrays a checkpoint
    holds, while some pieces sleep and others move, continues bit for bit."""
    sim = fragments()
    ms = sim.state.mech
    records, forked = [], None
    for r in debris.drop(sim, 0.05, 8.0):
        records.append(r)
        if len(records) > 5 and all(q.asleep == q.pieces for q in records[-5:]):
            break  # asleep for 0.5 s
        if forked is None and 0 < r.asleep < r.pieces:
            forked = mechanics.initial_state(sim.model)
            for k, v in ms.arrays().items():
                setattr(forked, k, v.copy())
            forked.t_seconds, forked.failures = ms.t_seconds, ms.failures
            twin = ms.copy()
            for s in (twin, forked):
                state = sim.state.copy()
                state.mech = s
                mechanics.macro_step(sim.model, state, 3000)
            assert sleep_digest(twin) == sleep_digest(forked)
            assert 0 < np.unique(twin.component[twin.asleep]).size < r.pieces
    assert forked is not None
    settled = next(k for k in range(len(records)) if all(r.asleep == r.pieces for r in records[k:]))
    print(f"pieces {records[-1].pieces}, settled at {records[settled].t:.1f} s, penetration "
          f"{max(r.penetration for r in records[settled:]):.3f} r_s, window speed before "
          f"{records[settled - 1].window_speed:.2e} m/s")
    assert records[0].max_speed > 0.1  # it fell
    assert records[-1].max_speed < 1e-3 and records[-1].asleep == records[-1].pieces
    assert all(r.penetration < 0.1 for r in records[settled:])
    assert records[-1].z_min > 0.0
