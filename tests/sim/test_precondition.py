"""The implicit step's preconditioner (wooddecay.sim.precondition): its coarse space holds the
rigid motions, it is symmetric positive definite, and it solves the Newton system of the tiny
log on the ground in fewer conjugate-gradient iterations than Jacobi."""
import numpy as np
import scipy.sparse.linalg as spla

from wooddecay.sim import implicit, mechanics, precondition

from ..conftest import sample
from .helpers import initial_state


def _tiny():
    model = sample("tiny")[1]
    ms = initial_state(model, rods=True).mech
    mechanics.set_masses(model.mech, ms, np.full(model.mech.n_elements, 0.5))
    return model.mech, ms


def _rigid(setup, ms, move: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """The whole wood moved by ``move`` and turned about its centroid by ``turn``: particles by
    move + turn x (x - c), element rotations by turn."""
    v = np.zeros((setup.n_particles + setup.n_elements, 3))
    v[:setup.n_particles] = move + np.cross(turn, ms.x - ms.x.mean(axis=0))
    v[setup.n_particles:] = turn
    return v.ravel()


def test_the_coarse_space_holds_every_rigid_motion_of_the_wood():
    setup, ms = _tiny()
    agg = precondition.aggregates(setup, ms)
    assert 1 < agg.max() + 1 < setup.n_elements
    modes = precondition.rigid_modes(setup, ms, agg).toarray()
    zero = np.zeros(3)
    for axis in np.eye(3):
        for g in (_rigid(setup, ms, axis, zero), _rigid(setup, ms, zero, axis)):
            y = np.linalg.lstsq(modes, g, rcond=None)[0]
            assert np.abs(modes @ y - g).max() <= 1e-9 * np.abs(g).max()
    # and no more than rigid motions: a bend of the wood is outside it
    bend = np.zeros((setup.n_particles + setup.n_elements, 3))
    bend[:setup.n_particles, 2] = (ms.x[:, 0] - ms.x[:, 0].mean()) ** 2
    y = np.linalg.lstsq(modes, bend.ravel(), rcond=None)[0]
    assert np.abs(modes @ y - bend.ravel()).max() > 1e-6 * np.abs(bend).max()


def test_the_two_level_preconditioner_is_symmetric_positive_and_beats_jacobi():
    setup, ms = _tiny()
    A, _, lay, modes = implicit.first_system(setup, ms, 0.01)
    M = precondition.two_level(A, lay.strand, lay.position, modes)
    rng = np.random.default_rng(0)
    u, v = rng.normal(size=(2, A.shape[0]))
    assert abs(u @ M.matvec(v) - v @ M.matvec(u)) <= 1e-10 * np.linalg.norm(u) * np.linalg.norm(M.matvec(v))
    assert min(w @ M.matvec(w) for w in rng.normal(size=(5, A.shape[0]))) > 0.0
    b = rng.normal(size=A.shape[0])
    counts = {}
    for name, pre in (("jacobi", None), ("two-level", M)):
        residuals: list[float] = []
        y, info = spla.cg(A, b, rtol=1e-6, maxiter=20000, M=pre,
                          callback=lambda yk: residuals.append(float(np.linalg.norm(A @ yk - b))))  # noqa: B023
        assert info == 0
        assert np.linalg.norm(A @ y - b) <= 1e-6 * np.linalg.norm(b)
        counts[name] = len(residuals)
    assert counts["two-level"] < 0.5 * counts["jacobi"], counts
