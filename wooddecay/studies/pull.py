"""Pull test (woodstock Fig. 17; docs/model.md §4 "Loads"): the smallest horizontal pull that breaks a
side branch, healthy and decayed, each found by bisection on a log scale.

Used by ``benchmarks/pull.py`` (the branch through node ``b1_2`` of ``samples/tree.toml``, in the
whole tree and cut out as a specimen at the tree's resolution) and ``tests/studies/test_pull.py`` (the
specimen at ``quality = "draft"``). docs/decisions.md ("Mechanics") gives reasons and figures.

* **Load.** One ``[[load]]`` appended to the scene (:func:`pull_scene`): the elements within
  ``radius`` of the skeleton node ``tip`` (by default the last node on the branch's axis), a
  horizontal force along the branch's horizontal direction, from its fork towards ``tip``
  (Fig. 17's "leftward pull to the left branch"). :func:`wooddecay.sim.mechanics.prepare` spreads
  it over the region's particles by mass; the scene's force is 1 N and a probe of F newtons
  scales those particle forces by F.
* **Limits.** Eq. 19 as printed (``mechanics.L_knee = 1``: the limits fall from M_1 down, so the
  green wood, M 0.5, keeps 4% of L_0): with the knee at M_0 the healthy branch keeps L_0, bends
  past the 5 cm break displacement (at about 36 N) before anything fails and the study measured
  its elastic sag, not its strength (docs/decisions.md, "Pull test").
* **Specimen** (:func:`specimen_scene`): the same scene with the skeleton cut down to the branch,
  clamped at its fork (an anchored root node at the fork with the first branch node's profile;
  for b1_2 the trunk there is 34 times stiffer in bending than the branch) and the BSP cells
  scaled with the wood volume so that cells keep their size.
* **Cases** (:func:`pull_cases`). The rods settle once with the initial fields (the scene's
  ``settle`` seconds at ``settle_damping``, as ``wd.Simulation`` does, and on until the strains
  drift by less than ``SETTLE_TOL`` of their limits within 0.05 s). From that equilibrium each
  case settles again for ``resettle`` seconds (default: the scene's ``settle``), on to the same
  tolerance, and takes its own reference strains (a decayed branch, softer, is overdamped at
  ``settle_damping`` and still sagging after 0.2 s, 0.4 mm more with no load in the draft
  specimen, a sag that would count against its weakened limits): *healthy* as it is, *decayed* after H_c = H_l =
  ``decay`` in every element and the coupling (Eq. 21: I_ij = (1 - theta_ij k_c (1 - H_c))
  (1 - k_l (1 - H_l)), which scales the pairs' stiffness and strain limits). The whole wood
  decays, as in Fig. 17, where the tree's health is lowered and "the connection loses
  integrity early": decaying the branch alone leaves the fork's connections to the healthy
  trunk at I 0.56-0.75, and the branch breaks beyond its weakened base at more than 0.22 N in
  the tree against 0.16-0.17 N for the specimen, whose clamp is branch wood (docs/decisions.md).
  The study's ``region`` can limit the decay to the branch with its junction
  (:func:`branch_elements`: the branch, its side branches and the wood within 1.5 fork radii of
  the fork, so the fork's connections decay too).
  Decay takes months: the branch sags into its weakened connections quasi-statically rather
  than being dropped from its rest pose, and both cases share the same settling history. Every
  probe starts from a copy of its case's settled :class:`~wooddecay.sim.mechanics.MechState`.
* **Probe** (:func:`probe`). ``seconds`` of mechanics (the scene's dt_mech, damping, gravity,
  failure on) under the constant pull F. The branch **breaks** when within that time the
  mass-weighted centroid of the loaded particles moves more than ``displacement`` from its
  settled position (the branch has lost its bending capacity and swings or sags away), or at
  least half of the loaded mass lies in pieces without an anchored element (it came off).
  Checked every ``check_every`` substeps; a probe stops at the first break. Coming off alone is
  no criterion: strand joints have no bending limit, so a branch whose base has failed still
  hangs on strands that the pull now loads in tension (a strand holds about E pi r_s^2 L(M)),
  and it swings and sags for a long time before the last one snaps.
* **Threshold** (:func:`threshold`). Bisection on log F: the bracket [lo, hi] is widened by
  ``grow`` until hi breaks and lo does not, then split at its geometric mean until hi / lo <= 1 +
  ``rel``. The threshold is the geometric mean of the final bracket.
"""
from __future__ import annotations

import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..wood import WoodModel
from ..model import build_model
from ..scene import Scene, load_scene, parse_scene
from ..sim import coupling, mechanics
from ..sim.driver import Simulation
from ..strands.regions import region_mask
from ..strands.topology import build_topology

#: the sample tree (the same file as the repository's ``samples/tree.toml``)
TREE = Path(__file__).resolve().parent.parent / "samples" / "tree.toml"
#: H_c = H_l of the decayed branch: I_ij = 0.5 (0.25 across BSP cells)
DECAY = 0.5
#: loaded seconds of a probe: the slowest breaks near the thresholds come at 0.24 s
SECONDS = 0.3
#: displacement of the load centroid (m) that counts as a break; unbroken branches stay below 2 cm
DISPLACEMENT = 0.05
#: settling goes on until no strain that can fail drifts by more than this fraction of its limit
#: within 0.05 s (:func:`wooddecay.sim.mechanics.settle`): a decayed branch is still sagging
#: after the scene's 0.2 s, and without load that sag alone broke it (docs/decisions.md)
SETTLE_TOL = 0.01


# ------------------------------------------------------------------ scenes
def _subtree(skel, branch: np.ndarray, node: str) -> list[int]:
    """Node indices of the branch through ``node`` and its side branches (``branch``: the
    topology's branch id per node): the subtree that starts at the branch's first node, the one
    whose parent lies on another branch."""
    i = skel.ids.index(node)
    first = i
    while skel.parent[first] >= 0 and branch[skel.parent[first]] == branch[i]:
        first = skel.parent[first]
    if skel.parent[first] < 0:
        raise ValueError(f"node {node!r} is on the trunk, not on a side branch")
    nodes = [first]
    for k in range(first + 1, len(skel.ids)):  # parents precede children
        if skel.parent[k] in nodes:
            nodes.append(k)
    return nodes


def _pull_direction(skel, nodes: list[int], tip: int) -> np.ndarray:
    """Unit horizontal vector from the fork of the subtree ``nodes`` towards node ``tip``."""
    d = skel.positions[tip] - skel.positions[skel.parent[nodes[0]]]
    d = np.array([d[0], d[1], 0.0])
    return d / np.linalg.norm(d)


def pull_scene(path=TREE, node: str = "b1_2", tip: str | None = None, radius: float = 0.15,
               specimen: bool = False, quality: str | None = None) -> Scene:
    """The scene at ``path`` plus the pull ``[[load]]`` (module docstring) of 1 N on the branch
    through ``node``; ``tip`` defaults to the last node on the branch's axis. With
    ``specimen`` the skeleton is cut down to that branch (:func:`specimen_scene`); ``quality``
    overrides ``[scene] quality``."""
    path = Path(path)
    data = tomllib.loads(path.read_text("utf-8"))
    base = load_scene(path)
    skel = base.skeleton
    branch = build_topology(skel).branch
    nodes = _subtree(skel, branch, node)
    # by default the last node on the branch's own axis
    k_tip = [k for k in nodes if branch[k] == branch[nodes[0]]][-1] if tip is None else skel.ids.index(tip)
    direction = _pull_direction(skel, nodes, k_tip)
    if specimen:
        data = _specimen_data(data, base, nodes)
    if quality is not None:
        data.setdefault("scene", {})["quality"] = quality
    data.setdefault("mechanics", {})["L_knee"] = 1.0  # Eq. 19 as printed (module docstring)
    data.setdefault("bark", {})["cracks"] = False  # Fig. 17 pulls the wood; its bark does not crack
    data["load"] = data.get("load", []) + [{
        "region": {"kind": "node", "id": skel.ids[k_tip], "radius": float(radius)},
        "force": [float(c) for c in direction], "days": [0.0, 1e9]}]
    return parse_scene(data, source=str(path), base_dir=path.parent)


def _frustum_volume(skel, nodes, radius_of) -> float:
    v = 0.0
    for k in nodes:
        p = skel.parent[k]
        if p >= 0:
            ra, rb = radius_of(p), radius_of(k)
            v += np.pi / 3.0 * np.linalg.norm(skel.positions[k] - skel.positions[p]) * (ra * ra + ra * rb + rb * rb)
    return v


def _specimen_data(data: dict, scene: Scene, nodes: list[int]) -> dict:
    """Scene data whose skeleton is the branch ``nodes`` alone, clamped at its fork: an anchored
    root node at the fork with the profile of the branch's first node. Inoculations are dropped
    (they may name nodes that are gone); the BSP keeps the tree's cell size
    (cells scaled by the skeleton volume)."""
    skel = scene.skeleton
    first = nodes[0]
    fork = skel.parent[first]
    profiles = {n["id"]: n["profile"] for n in scene.to_dict()["skeleton"]["nodes"]}
    root = {"id": "stump", "position": [float(c) for c in skel.positions[fork]], "anchored": True,
            "profile": profiles[skel.ids[first]]}
    out = [root]
    for k in nodes:
        par = "stump" if k == first else skel.ids[skel.parent[k]]
        out.append({"id": skel.ids[k], "position": [float(c) for c in skel.positions[k]], "parent": par,
                    "profile": profiles[skel.ids[k]]})
    data = {k: v for k, v in data.items() if k not in ("skeleton", "inoculation", "load")}
    data["skeleton"] = {"node": out}

    def radius(k):
        return skel.profiles[k].equivalent_radius

    def cut_radius(k):  # the specimen's root takes the first node's profile
        return radius(first if k == fork else k)

    share = _frustum_volume(skel, nodes, cut_radius) / _frustum_volume(skel, range(len(skel.ids)), radius)
    bsp = dict(data.get("bsp", {}))
    if bsp.get("cells", 0) > 0:
        bsp["cells"] = max(1, int(round(bsp["cells"] * share)))
        data["bsp"] = bsp
    return data


def specimen_scene(path=TREE, node: str = "b1_2", quality: str = "draft", **kw) -> Scene:
    """The branch through ``node`` cut out of the tree at ``path`` and clamped at its fork
    (the trunk of the tree is far stiffer than the branch), at ``quality``, with the pull load."""
    return pull_scene(path, node=node, specimen=True, quality=quality, **kw)


# ------------------------------------------------------------------ cases and probes
@dataclass(eq=False)
class PullCase:
    """A settled model ready to be pulled (module docstring)."""

    name: str
    model: object  # WoodModel (with the 1 N pull as its load)
    settled: object  # SimState after settling
    unit_force: np.ndarray  # (P, 3) particle forces of a 1 N pull
    loaded_p: np.ndarray  # particles the pull acts on
    weight_p: np.ndarray  # their share of the force (sums to 1)
    loaded_e: np.ndarray  # (n,) bool: elements of the load region
    settle_seconds: float  # wall time of its own settling (after the shared first one)
    base_settle_seconds: float  # wall time of the first settling, shared by both cases
    settled_seconds: float  # mechanics seconds of its own settling (converged to SETTLE_TOL)


def branch_elements(model: WoodModel, node: str = "b1_2", junction: float = 1.5) -> np.ndarray:
    """(n,) bool: the elements of the branch through ``node`` and its side branches, and those
    of the wood within ``junction`` times the fork node's radius of the fork (the connection of
    the branch to its parent)."""
    skel = model.skeleton
    branch = model.topology.branch
    nodes = _subtree(skel, branch, node)
    fork = skel.parent[nodes[0]]
    r = junction * skel.profiles[fork].equivalent_radius
    near = np.linalg.norm(model.centers - skel.positions[fork], axis=1) <= r
    return near | np.isin(model.branch, branch[nodes])


def pull_cases(scene: Scene, model=None, decay: float = DECAY, resettle: float | None = None,
               region: np.ndarray | None = None, tol: float | None = SETTLE_TOL
               ) -> tuple[PullCase, PullCase]:
    """The healthy and the decayed case of ``scene`` (its model built if not given).

    Module docstring, "Cases"; ``resettle`` defaults to the scene's ``settle``; ``region``
    (elements, bool) limits the decay to those elements (default: all); ``tol`` is the settling
    tolerance (None: fixed times only)."""
    model = build_model(scene) if model is None else model
    sim = Simulation(model, settle=False)
    setup = model.mech
    if len(setup.loads) != 1:
        raise ValueError("the pull scene must have exactly one [[load]]")
    unit = mechanics.external_forces(setup, setup.loads[0][0])
    unit = unit / np.linalg.norm(unit.sum(axis=0))
    mag = np.linalg.norm(unit, axis=1)
    loaded_p = np.flatnonzero(mag > 0.0)
    loaded_e = region_mask(model, scene.loads[0]["region"])
    damping = scene.mechanics.settle_damping
    resettle = scene.mechanics.settle if resettle is None else resettle
    t0 = time.perf_counter()
    mechanics.settle(model, sim.state, scene.mechanics.settle, damping, tol=tol)
    first = time.perf_counter() - t0
    base = sim.state.mech.copy()

    def case(name):
        t0 = time.perf_counter()
        settled = mechanics.settle(model, sim.state, resettle, damping, tol=tol)
        return PullCase(name=name, model=model, settled=sim.state.copy(), unit_force=unit, loaded_p=loaded_p,
                        weight_p=mag[loaded_p] / mag[loaded_p].sum(), loaded_e=loaded_e,
                        settle_seconds=time.perf_counter() - t0, base_settle_seconds=first,
                        settled_seconds=settled)

    healthy = case("healthy")
    sim.state.mech = base
    where = slice(None) if region is None else region
    sim.state.H_c[where] = decay
    sim.state.H_l[where] = decay
    coupling.step(model, sim.state)  # Eq. 21 and the limits from the new fields
    return healthy, case("decayed")


@dataclass(frozen=True)
class Probe:
    force: float  # N
    broke: bool
    t_break: float | None  # s of loaded time at the break
    reason: str  # "displaced", "separated" or ""
    max_displacement: float  # m, of the load centroid over the probe
    detached: float  # largest fraction of the loaded mass separated from the stump
    failures: int  # failure events during the probe
    t_last_failure: float | None  # s: the check at which the failure count last grew (None: none)
    seconds: float  # loaded time simulated
    wall: float  # s


def probe(case: PullCase, force: float, seconds: float = SECONDS, displacement: float = DISPLACEMENT,
          check_every: int = 10, trace: list | None = None) -> Probe:
    """Pull the settled ``case`` with ``force`` newtons for up to ``seconds`` (module docstring);
    ``trace`` collects (t, displacement, detached fraction, failures) at every check."""
    setup = case.model.mech
    state = case.settled.copy()
    ms = state.mech
    ms.pairs_x = None  # rebuild the contact list from this state
    ms.force = force * case.unit_force
    x0 = case.weight_p @ ms.x[case.loaded_p]
    failures0 = ms.failures
    anchored = setup.anchored_e
    loaded_w = setup.dry_mass * case.loaded_e
    loaded_w = loaded_w / loaded_w.sum()
    n = int(round(seconds / setup.dt))
    d_max = detached = 0.0
    t0 = time.perf_counter()
    reason, k, last, t_last = "", 0, failures0, None
    while k < n:
        step = min(check_every, n - k)
        mechanics.advance(case.model, state, step)
        k += step
        d_max = max(d_max, float(np.linalg.norm(case.weight_p @ ms.x[case.loaded_p] - x0)))
        now = float(loaded_w[~np.isin(ms.component, ms.component[anchored])].sum())
        detached = max(detached, now)
        if ms.failures > last:
            last, t_last = ms.failures, k * setup.dt
        if trace is not None:
            trace.append((k * setup.dt, d_max, now, ms.failures - failures0))
        if d_max > displacement:
            reason = "displaced"
        elif detached >= 0.5:
            reason = "separated"
        if reason:
            break
    return Probe(force=float(force), broke=bool(reason), t_break=k * setup.dt if reason else None, reason=reason,
                 max_displacement=d_max, detached=detached, failures=ms.failures - failures0,
                 t_last_failure=t_last, seconds=k * setup.dt, wall=time.perf_counter() - t0)


@dataclass
class Threshold:
    """Bracket [lo, hi] of the breaking force: ``hi`` broke, ``lo`` did not."""

    case: str
    lo: float
    hi: float
    probes: list = field(default_factory=list)

    @property
    def force(self) -> float:
        """Geometric mean of the bracket."""
        return float(np.sqrt(self.lo * self.hi))

    def at(self, force: float) -> Probe:
        return next(p for p in self.probes if p.force == force)


def threshold(case: PullCase, lo: float, hi: float, seconds: float = SECONDS, displacement: float = DISPLACEMENT,
              rel: float = 0.1, grow: float = 4.0, max_probes: int = 16, log=None) -> Threshold:
    """Bisect the breaking force of ``case`` on a log scale, starting from the guess [lo, hi]
    (module docstring); ``log(case name, probe)`` is called after every probe."""
    probes: list[Probe] = []

    def run(F):
        p = probe(case, F, seconds, displacement)
        probes.append(p)
        if log is not None:
            log(case.name, p)
        if len(probes) > max_probes:
            raise RuntimeError(f"{case.name}: no bracket after {max_probes} probes (forces "
                               f"{[q.force for q in probes]} N); does it break under its own weight?")
        return p.broke

    while not run(hi):
        lo, hi = hi, hi * grow
    if not any(p.force == lo for p in probes):
        while run(lo):
            lo, hi = lo / grow, lo
    while hi / lo > 1.0 + rel:
        mid = float(np.sqrt(lo * hi))
        if run(mid):
            hi = mid
        else:
            lo = mid
    return Threshold(case=case.name, lo=lo, hi=hi, probes=probes)


@dataclass
class PullStudy:
    """Both thresholds of one scene (:func:`study`)."""

    healthy: Threshold
    decayed: Threshold
    n_elements: int
    loaded_elements: int
    settle_seconds: float  # wall time of all settling
    settled: tuple  # mechanics seconds each case settled for (healthy, decayed)
    seconds: float  # loaded time of a probe
    displacement: float

    @property
    def ratio(self) -> float:
        """Healthy over decayed threshold (geometric means of the brackets)."""
        return self.healthy.force / self.decayed.force

    @property
    def ratio_min(self) -> float:
        """The smallest ratio the brackets allow: healthy lo over decayed hi."""
        return self.healthy.lo / self.decayed.hi


def study(scene: Scene, model=None, healthy=(2.0, 4.0), decayed=(0.1, 0.3), rel: float = 0.1,
          seconds: float = SECONDS, displacement: float = DISPLACEMENT, decay: float = DECAY,
          region: np.ndarray | None = None, log=None) -> PullStudy:
    """Settle both cases of ``scene`` and bisect their thresholds from the guesses ``healthy``
    and ``decayed`` (brackets in N; widened automatically when wrong); ``region`` (elements,
    bool) limits the decay (default: all the wood; :func:`branch_elements`)."""
    model = build_model(scene) if model is None else model
    h, d = pull_cases(scene, model, decay=decay, region=region)
    th = threshold(h, *healthy, seconds, displacement, rel=rel, log=log)
    td = threshold(d, *decayed, seconds, displacement, rel=rel, log=log)
    return PullStudy(healthy=th, decayed=td, n_elements=model.n_elements, loaded_elements=int(h.loaded_e.sum()),
                     settle_seconds=h.base_settle_seconds + h.settle_seconds + d.settle_seconds,
                     settled=(h.settled_seconds, d.settled_seconds),
                     seconds=seconds, displacement=displacement)
