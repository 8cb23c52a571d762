"""Bark cracks and shedding (wooddecay.bark, wooddecay.sim.bark; docs/model.md §10, woodification §5)."""
from __future__ import annotations

from dataclasses import replace

import numba
import numpy as np
import pytest

import wooddecay as wd
from wooddecay.bake import bake
from wooddecay.bark import cracks, shedding
from wooddecay.export import bark_surface as surface
from wooddecay.export import bark_texture as texture
from wooddecay.export.png import png16
from wooddecay.bark.sheet import recent_growth
from wooddecay.meshlets.checks import closed_oriented
from wooddecay.meshlets.sweep import build_meshlets
from wooddecay.sim import bark
from wooddecay.sim.driver import Simulation

from ..conftest import SAMPLES


def _model(**sets):
    return wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", overrides=sets))


@pytest.fixture(scope="module")
def tiny_bark():
    return _model()


def _load(sheet, st, eps, tip_gain=3.0, shadow=0.02, stages=10):
    for k in range(1, stages + 1):
        cracks.grow(sheet, st, eps * k / stages, tip_gain, shadow)


def test_tensor_algebra_matches_numpy():
    rng = np.random.default_rng(3)
    T = rng.normal(size=(200, 3))
    l1, l2, e = cracks.eig2(T)
    for k in range(len(T)):
        A = np.array([[T[k, 0], T[k, 2]], [T[k, 2], T[k, 1]]])
        w, v = np.linalg.eigh(A)
        assert np.allclose([l2[k], l1[k]], w)
        assert abs(abs(e[k] @ v[:, 1]) - 1.0) < 1e-9
    # a crack with normal n leaves only the stress along it: Pi sigma Pi = (t.sigma.t) t t^T
    n = np.array([np.cos(0.4), np.sin(0.4)])
    t = np.array([-n[1], n[0]])
    S = np.tile([n[0] ** 2, n[1] ** 2, n[0] * n[1]], (len(T), 1))
    out = cracks.relieved(T, S)
    along = T[:, 0] * t[0] ** 2 + T[:, 1] * t[1] ** 2 + 2 * T[:, 2] * t[0] * t[1]
    assert np.allclose(out, along[:, None] * np.array([t[0] ** 2, t[1] ** 2, t[0] * t[1]]))


@pytest.mark.parametrize("scene", ["log.toml", "meshes/forked_branch.toml"])
def test_shadows_from_the_grid_equal_the_kd_tree_reference(scene):
    """cast_shadows finds the faces of each crack edge's strip in the sheet's grid and adds the
    same bits as the KD-tree reference, which visits every face within reach (around each
    branch of the forked one); the faces it skips get no shadow there."""
    sheet = wd.build_model(wd.load_scene(SAMPLES / scene)).bark
    rng = np.random.default_rng(3)
    g = sheet.face_grid
    assert np.array_equal(np.sort(g.faces), np.arange(sheet.n_faces)) and g.ptr[-1] == sheet.n_faces
    for count in (1, 40, 600):
        new = np.unique(rng.integers(0, len(sheet.edges), count))
        a = cracks.CrackState.empty(sheet)
        a.shadow[:] = rng.random(a.shadow.shape)
        b = cracks.CrackState(cracked=a.cracked.copy(), shadow=a.shadow.copy())
        before = a.shadow.copy()
        fa = cracks.cast_shadows(sheet, a, new, 0.02)
        fb = cracks.cast_shadows_reference(sheet, b, new, 0.02)
        np.testing.assert_array_equal(a.shadow, b.shadow)
        assert len(fa) and np.isin(fa, fb).all()
        np.testing.assert_array_equal(a.shadow[np.setdiff1d(fb, fa)], before[np.setdiff1d(fb, fa)])
    assert len(cracks.cast_shadows(sheet, a, np.zeros(0, dtype=np.int64), 0.02)) == 0


def test_eig2_equals_its_numpy_reference():
    """The numba eigenpairs are numpy's: the eigenvalues to the bit, the eigenvectors within
    rounding (both take libm's atan2, cos and sin here; numpy may vectorise them elsewhere), on
    random tensors, isotropic ones, zeros of either sign and a wide range of magnitudes."""
    rng = np.random.default_rng(5)
    T = rng.normal(size=(6000, 3)) * 10.0 ** rng.integers(-8, 4, size=(6000, 1))
    T[::5, 2] = 0.0
    T[1::5, 1] = T[1::5, 0]
    T[2::5] = 0.0
    T[3::5] = -0.0
    T[4::10, 2] = -0.0
    l1, l2, e = cracks.eig2(T)
    r1, r2, re = cracks.eig2_reference(T)
    np.testing.assert_array_equal(l1, r1)
    np.testing.assert_array_equal(l2, r2)
    np.testing.assert_allclose(e, re, rtol=0.0, atol=4e-16)
    np.testing.assert_allclose(np.hypot(e[:, 0], e[:, 1]), 1.0, rtol=0.0, atol=4e-16)


def test_relieved_and_tensile_equal_their_numpy_references():
    """The numba products give numpy's bits, signed zeros included."""
    rng = np.random.default_rng(4)
    T = rng.normal(size=(5000, 3))
    S = np.abs(rng.normal(size=(5000, 3))) * 0.7
    S[::3] = 0.0
    T[::7] = -0.0
    for a, b in ((cracks.relieved(T, S), cracks.relieved_reference(T, S)),
                 (cracks.tensile(T), cracks.tensile_reference(T))):
        np.testing.assert_array_equal(a, b)
        assert np.array_equal(np.signbit(a), np.signbit(b))


def test_separation_equals_its_numpy_reference(tiny_bark):
    sheet = tiny_bark.bark
    rng = np.random.default_rng(5)
    plus = rng.normal(size=(sheet.n_faces, 3))
    plus[rng.random(sheet.n_faces) < 0.3] = -0.0  # the sign of a zero survives as numpy's sum keeps it
    np.testing.assert_array_equal(cracks.separation(sheet, plus), cracks.separation_reference(sheet, plus))
    some = rng.integers(0, len(sheet.phi), 50)
    got, want = cracks.separation(sheet, plus, some), cracks.separation_reference(sheet, plus, some)
    np.testing.assert_array_equal(got, want)
    assert np.array_equal(np.signbit(got), np.signbit(want))


def test_recent_growth_is_the_outer_rings_share():
    Q = np.linspace(0.0, 1.0, 11)  # ten equal rings
    assert recent_growth(Q, 3) == pytest.approx(0.3)
    assert recent_growth(Q, 50) == pytest.approx(1.0)


def test_circumferential_tension_cracks_along_the_axis(tiny_bark):
    sheet = replace(tiny_bark.bark, pattern=(1.0, 0.0))  # pure tension around the cylinder
    st = cracks.CrackState.empty(sheet)
    _load(sheet, st, np.full(sheet.n_faces, 0.1))
    stats = cracks.statistics(sheet, st.cracked)
    assert stats["bark_crack_count"] >= 2
    assert stats["bark_crack_along_grain"] > 0.8
    # tension along the grain cracks around the cylinder instead
    sheet = replace(tiny_bark.bark, pattern=(0.0, 1.0))
    st = cracks.CrackState.empty(sheet)
    _load(sheet, st, np.full(sheet.n_faces, 0.1))
    assert cracks.statistics(sheet, st.cracked)["bark_crack_along_grain"] < 0.2


def test_incremental_search_ends_where_a_full_one_finds_nothing(tiny_bark):
    """grow() re-evaluates only the vertices the new shadows reached; evaluated from scratch
    afterwards, no vertex may still crack."""
    sheet, b = tiny_bark.bark, tiny_bark.bark_setup
    st = cracks.CrackState.empty(sheet)
    eps = np.full(sheet.n_faces, 0.08)
    _load(sheet, st, eps, tip_gain=b.tip_gain, shadow=b.shadow)
    plus = cracks.tensile(cracks.relieved(cracks.loading(sheet, eps), st.shadow))
    l1, _, e1 = cracks.eig2(cracks.separation(sheet, plus))
    deg = cracks.crack_degree(sheet, st.cracked)
    assert st.cracked.any()
    assert len(cracks._new_edges(sheet, st, deg, l1, e1, b.tip_gain)) == 0


def test_zero_stress_never_cracks(tiny_bark):
    sheet = tiny_bark.bark
    st = cracks.CrackState.empty(sheet)
    _load(sheet, st, np.zeros(sheet.n_faces))
    assert not st.cracked.any()
    model = _model(**{"bark.growth": 0.0, "bark.drying": 0.0})
    sim = Simulation(model, mechanics=False)
    for _ in sim.run():
        pass
    assert bark.statistics(model, sim.state.bark)["bark_crack_count"] == 0


def test_patterns_differ_measurably():
    share = {}
    for species in ("oak", "spruce"):
        model = _model(**{"bark.species": species, "bark.growth": 0.05})
        st = bark.initial(model, wd.Simulation(model, mechanics=False).state)
        share[species] = bark.statistics(model, st)["bark_crack_along_grain"]
    assert share["oak"] > share["spruce"] + 0.15


def test_cracks_do_not_depend_on_threads():
    runs = []
    for n in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
        numba.set_num_threads(n)
        model = _model(**{"climate.preset": "dry", "time.days": 120, "bark.growth": 1.0})
        sim = Simulation(model, mechanics=False)
        for _ in sim.run():
            pass
        runs.append(sim.state.bark.arrays())
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    for k in runs[0]:
        assert np.array_equal(runs[0][k], runs[1][k]), k
    assert runs[0]["cracked"].any()


def test_drying_adds_cracks():
    model = _model(**{"climate.preset": "dry", "time.days": 180, "bark.growth": 0.05})
    sim = Simulation(model, mechanics=False)
    counts = [bark.statistics(model, sim.state.bark)["bark_crack_length_m"]]
    for _ in sim.run():
        counts.append(bark.statistics(model, sim.state.bark)["bark_crack_length_m"])
    assert counts[-1] > counts[0] * 1.2
    assert counts == sorted(counts)  # cracks never heal


def test_grooves_keep_meshlets_closed_and_shared(tiny_bark):
    model = replace(tiny_bark, bark_setup=replace(tiny_bark.bark_setup, groove_width=1e-4))
    mesh = build_meshlets(model)
    st = cracks.CrackState.empty(model.bark)
    _load(model.bark, st, np.full(model.bark.n_faces, 0.1))
    crack, depth, width = surface.crack_fields(model, mesh, st.cracked)
    assert crack.max() == pytest.approx(1.0, abs=0.3) and depth.max() > 0.0
    assert not crack[~surface.bark_vertices(mesh)].any()
    off = surface.groove_offsets(model, mesh, depth, width)
    moved = np.linalg.norm(off, axis=1)
    assert moved.max() > 0.0 and moved.max() <= 0.5 * min(model.bark_thickness, model.r_s) + 1e-12
    grooved = replace(mesh, points=mesh.points + off)
    assert closed_oriented(grooved).all()
    # every copy of a shared vertex moves alike: the meshlets still meet without gaps
    order = np.argsort(mesh.vertex_shared, kind="stable")
    sh, P = mesh.vertex_shared[order], grooved.points[order]
    same = sh[1:] == sh[:-1]
    assert np.abs(P[1:][same] - P[:-1][same]).max() < 1e-12
    # the grooves point inwards: every grooved meshlet keeps a positive volume
    F = grooved.faces
    X = grooved.points
    vol = np.einsum("ij,ij->i", X[F[:, 0]], np.cross(X[F[:, 1]], X[F[:, 2]])) / 6.0
    assert (np.bincount(grooved.face_element, weights=vol) > 0).all()


def test_plates_shed_and_come_loose(tiny_bark):
    model = tiny_bark
    sheet = model.bark
    st = cracks.CrackState.empty(sheet)
    _load(sheet, st, np.full(sheet.n_faces, 0.1))
    label = shedding.plates(sheet, st.cracked, np.zeros(sheet.n_faces, dtype=bool))
    plate_area = 0.01
    out, off, breaks = shedding.falling(sheet, label, np.full(sheet.n_faces, -1.0), plate_area)
    assert off.any()
    # plates larger than plate_area broke into plates of about it, along new cracks
    area = np.bincount(out[off], weights=sheet.face_area[off])
    assert area[area > 0].max() <= 2.5 * plate_area
    assert len(breaks) and not st.cracked[breaks].all()
    held = shedding.falling(sheet, label, np.ones(sheet.n_faces), plate_area)[1]
    assert not held.any()
    edge_cut, link_cut, plate = shedding.cuts(model, sheet, out, off)
    assert (plate >= 0).sum() > 0.5 * (sheet.element_face >= 0).sum()
    # after the cuts no intact pair or link joins an element to another plate or to the wood
    i, j = model.reg_edges.T
    assert (plate[i][~edge_cut] == plate[j][~edge_cut]).all()
    e1 = model.coupling.link_next
    assert (plate[~link_cut] == plate[e1][~link_cut]).all()
    # and no element needs cuts at both its strand links (two failures side by side part nothing)
    e = np.arange(model.n_elements)
    e0 = np.where((e > 0) & (model.strand[np.maximum(e - 1, 0)] == model.strand), e - 1, e)
    assert not (link_cut & link_cut[e0] & (e0 != e)).any()


def test_plates_are_scipys_components(tiny_bark):
    """The union-find kernel labels the plates as scipy's components on the face graph, for the
    grown cracks and for random cracks and shed faces (shed faces numbered as isolated ones)."""
    sheet = tiny_bark.bark
    st = cracks.CrackState.empty(sheet)
    _load(sheet, st, np.full(sheet.n_faces, 0.1))
    rng = np.random.default_rng(5)
    cases = [(st.cracked, np.zeros(sheet.n_faces, dtype=bool))]
    cases += [(rng.random(len(sheet.edges)) < p, rng.random(sheet.n_faces) < p) for p in (0.02, 0.1, 0.3)]
    for cracked, shed in cases:
        label = shedding.plates(sheet, cracked, shed)
        np.testing.assert_array_equal(label, shedding.plates_reference(sheet, cracked, shed))
        assert (label[shed] == -1).all() and len(np.unique(label[~shed])) > 1


def test_members_equal_a_stable_argsort():
    """The faces of each plate, as falling() takes them, are a stable argsort's, shed faces left out."""
    label = np.random.default_rng(5).integers(-1, 40, 5000)
    label[label == 7] = -1  # a label with no face
    for a, b in zip(shedding._members(label, 40), shedding.members_reference(label, 40)):
        assert np.array_equal(a, b)


def test_broken_plate_edges_equal_numpy(tiny_bark):
    """The edges along which falling() parts a plate are its numpy twin's, with shed faces and
    the sheet's border edges (no second face)."""
    sheet = tiny_bark.bark
    rng = np.random.default_rng(4)
    label = rng.integers(-1, 5, sheet.n_faces)
    out = label * 3 + rng.integers(0, 3, sheet.n_faces)
    off = (label >= 0) & (rng.random(sheet.n_faces) < 0.5)
    broke = np.empty(len(sheet.edge_faces), dtype=bool)
    shedding._broke(sheet.edge_faces, label, out, off, broke)
    assert (sheet.edge_faces[:, 1] < 0).any() and broke.any()
    assert np.array_equal(broke, shedding.broke_reference(sheet.edge_faces, label, out, off))


def test_partition_spreads_plates_along_the_grain(tiny_bark):
    sheet = tiny_bark.bark
    faces = np.arange(sheet.n_faces)
    piece = shedding.partition(sheet, faces, 6)
    assert set(np.unique(piece)) == set(range(6))
    area = np.bincount(piece, weights=sheet.face_area)
    assert area.max() < 3.0 * area.min()


@pytest.mark.parametrize("threads", [1, 2])
def test_partition_kernel_equals_numpy_reference(tiny_bark, threads):
    """The farthest-point kernel gives the reference's pieces, bit for bit, on whole and scattered
    plates, for k from one site to more sites than faces, on any thread count."""
    sheet = tiny_bark.bark
    rng = np.random.default_rng(3)
    faces = np.arange(sheet.n_faces)
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        for sub in (faces, np.sort(rng.choice(faces, sheet.n_faces // 3, replace=False)), faces[:5]):
            for k in (1, 2, 9, 40):
                assert np.array_equal(shedding.partition(sheet, sub, k), shedding.partition_reference(sheet, sub, k))
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


def test_bonds_weaken_with_decay_and_cycles():
    b = np.ones(3)
    one = np.ones(3)
    out = shedding.weaken(b, 1.0, 365.25, np.array([1.0, 0.0, 1.0]), np.array([1.0, 0.0, 1.0]),
                          np.array([0.0, 0.0, 0.4]), np.full(3, 0.2))
    assert out == pytest.approx([1.0, 0.0, 0.0])
    assert (shedding.weaken(b, 0.0, 10.0, 0 * one, 0 * one, one, one) == 1.0).all()


def test_face_pass_equals_numpy_reference(tiny_bark):
    """The step's one pass over the faces gives the loading, bonds, moisture and counts of its
    numpy twin bit for bit, on one thread and two, with faces shed, rising and falling loads and
    bonds going past 0."""
    sheet = tiny_bark.bark
    n, F = tiny_bark.n_elements, sheet.n_faces
    rng = np.random.default_rng(3)
    M, H_c, H_l = rng.uniform(0.0, 0.6, n), rng.uniform(0.0, 1.0, n), rng.uniform(0.0, 1.0, n)
    bond, M_last, shed = rng.uniform(-0.1, 0.3, F), rng.uniform(0.0, 0.6, F), rng.random(F) < 0.2
    eps_seen = sheet.growth + 0.7 * bark.drying_strain(sheet, M[sheet.face_element]) * rng.uniform(0.5, 1.5, F)
    args = (sheet.face_element, M, H_c, H_l, sheet.growth, 0.7, sheet.shrinkage, sheet.M_0, 2.0, 4.0, eps_seen)
    ref = bond.copy(), M_last.copy(), np.empty(F)
    counts = bark.faces_reference(*args, ref[0], ref[1], shed, ref[2])
    assert 0 < counts[0] < F and 0 < counts[1] < F
    try:
        for t in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(t)
            out = bond.copy(), M_last.copy(), np.empty(F)
            assert bark._faces(*args, out[0], out[1], shed, out[2]) == counts
            for a, b in zip(out, ref):
                assert np.array_equal(a, b)
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


def test_bake_exports_crack_primvars_and_signature(tmp_path):
    scene = wd.load_scene(SAMPLES / "tiny.toml", overrides={"bark.growth": 2.0, "time.frames": 2})
    summary = bake(scene, tmp_path)
    sig = summary["frames"][-1]["signature"]
    assert sig["bark_crack_count"] > 0 and sig["bark_crack_length_m"] > 0
    assert 0.0 <= sig["bark_crack_along_grain"] <= 1.0 and sig["bark_shed_fraction"] == 0.0
    from pxr import Usd, UsdGeom

    from wooddecay.export.wood_read import wood_at, wood_meshes

    stage = Usd.Stage.Open(str(tmp_path / "tiny.usdc"))
    wood = wood_at(stage, 1.0)
    assert wood["bark_crack"].max() > 0.5 and wood["bark_crack_depth"].max() > 0.0
    assert len(wood["barkUV"]) == 3 * len(wood["faces"])
    for piece in wood_meshes(stage):
        uv = UsdGeom.PrimvarsAPI(piece).GetPrimvar("barkUV")
        assert uv.GetInterpolation() == UsdGeom.Tokens.faceVarying
        assert len(uv.Get()) == 3 * len(UsdGeom.Mesh(piece).GetFaceVertexCountsAttr().Get())
    assert stage.GetRootLayer().customLayerData["bark_texture"] == "tiny_bark.<UDIM>.png"
    tiles = sorted(p.name for p in tmp_path.glob("tiny_bark*"))
    assert tiles == ["tiny_bark.1001.png", "tiny_bark.1002.png"]  # one per frame
    last = _decode_png16((tmp_path / tiles[-1]).read_bytes())
    assert last.ndim == 2 and last.max() > 32768 and (last == 0).any()
    assert set(summary["outputs"]) >= set(tiles)
    import json
    import struct

    raw = (tmp_path / "tiny.glb").read_bytes()
    n = struct.unpack_from("<I", raw, 12)[0]
    gltf = json.loads(raw[20:20 + n])
    assert all("_BARK_CRACK" in p["attributes"] for m in gltf["meshes"] for p in m["primitives"])


def _decode_png16(data: bytes) -> np.ndarray:
    import struct
    import zlib

    w, h = struct.unpack(">II", data[16:24])
    i, idat = 8, b""
    while i < len(data):
        n = struct.unpack(">I", data[i:i + 4])[0]
        if data[i + 4:i + 8] == b"IDAT":
            idat += data[i + 8:i + 8 + n]
        i += 12 + n
    channels = {0: 1, 2: 3}[data[25]]  # IHDR colour type: grey or RGB
    rows = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).reshape(h, 1 + 2 * channels * w)
    assert (rows[:, 0] == 0).all()
    image = rows[:, 1:].copy().view(">u2").astype(np.uint16)
    return image.reshape(h, w) if channels == 1 else image.reshape(h, w, 3)


@pytest.mark.parametrize("shape", [(7, 9, 3), (7, 9)])
def test_png16_round_trip(shape):
    image = np.random.default_rng(5).integers(0, 65536, shape).astype(np.uint16)
    assert np.array_equal(_decode_png16(png16(image)), image)


def test_crack_maps_show_each_frame_its_own_cracks(tiny_bark):
    from types import SimpleNamespace

    sheet = tiny_bark.bark
    st = cracks.CrackState.empty(sheet)
    _load(sheet, st, np.full(sheet.n_faces, 0.05))
    first = st.cracked.copy()
    _load(sheet, st, np.full(sheet.n_faces, 0.1))
    cracked = (first * False, first, first, st.cracked)
    frames = [SimpleNamespace(index=k, bark={"cracked": c}) for k, c in enumerate(cracked)]
    tiles = texture.crack_maps(tiny_bark, frames)
    assert len(tiles) == 4 and (tiles[0] == 0).all() and np.array_equal(tiles[1], tiles[2])
    # more cracks by frame 3 than by 1; a frame's tile does not depend on the frames after it
    assert 0 < (tiles[1] > 0).sum() < (tiles[3] > 0).sum()
    assert np.array_equal(texture.crack_maps(tiny_bark, frames[:2])[1], tiles[1])
    assert texture.crack_maps(tiny_bark, [SimpleNamespace(index=0, bark={})]) is None
    # the atlas spans the sheet: one texel per h / TEXELS_PER_EDGE around and along
    texel = sheet.h / texture.TEXELS_PER_EDGE
    assert tiles[3].shape[1] == int(np.ceil(sheet.period.max() / texel))
    assert abs(tiles[3].shape[0] * texel - np.ptp(sheet.s)) < 2 * texel
    # 1,000 texels in a crack on each frame's map and 1,000 others, against every crack sample of
    # that frame (periodic around the branch, widths of that frame's cracks): the map's KD query,
    # bounded by the widest crack, gives the nearest crack's profile
    s0, first_row, count = texture._branch_rows(sheet, texel)
    for k in (1, 3):
        w_v = cracks.widths(sheet, cracked[k], float(tiny_bark.bark_setup.crack_width))
        pts, br, w = surface.crack_samples(sheet, cracked[k], w_v)
        for b in np.unique(br):
            on = br == b
            P, W = sheet.period[b], tiles[k].shape[1]
            tile = tiles[k][first_row[b]:first_row[b] + count[b]].ravel()
            rng = np.random.default_rng(int(b))
            sel = np.union1d(*(rng.choice(i, min(len(i), 1000), replace=False)
                               for i in (np.flatnonzero(tile > 0), np.flatnonzero(tile == 0))))
            r, c = np.divmod(sel, W)
            q = np.stack([(c + 0.5) / W * P, s0[b] + r * texel], 1)
            dx = np.abs(q[:, None, 0] - pts[on][None, :, 0] % P)
            d = np.hypot(np.minimum(dx, P - dx), np.clip(q[:, None, 1], pts[on, 1].min(), None) - pts[on][None, :, 1])
            i = d.argmin(1)
            g_ref = np.clip(1.0 - d[np.arange(len(q)), i] / np.maximum(w[on][i], 1e-12), 0.0, 1.0)
            assert (g_ref > 0).sum() > 100
            np.testing.assert_array_equal(tile[sel], np.round(g_ref * 65535.0).astype(np.uint16))


def test_crack_maps_keep_the_last_frame_past_udim(tiny_bark, monkeypatch):
    from types import SimpleNamespace

    sheet = tiny_bark.bark
    st = cracks.CrackState.empty(sheet)
    _load(sheet, st, np.full(sheet.n_faces, 0.1))
    frames = [SimpleNamespace(index=k, bark={"cracked": st.cracked * (k == 4)}) for k in range(5)]
    monkeypatch.setattr(texture, "MAX_TILES", 3)
    tiles = texture.crack_maps(tiny_bark, frames)
    assert len(tiles) == 3 and (tiles[1] == 0).all() and tiles[2].max() > 0


def test_bark_uv_unwraps_faces_across_the_seam(tiny_bark):
    mesh = build_meshlets(tiny_bark)
    F = mesh.faces[mesh.face_kind == surface.FACE_BARK]
    uv = texture.bark_uv(tiny_bark, mesh, F).reshape(-1, 3, 2)
    assert np.ptp(uv[..., 0], axis=1).max() < 0.25  # no face stretches around the branch
    assert uv[..., 1].min() >= 0.0 and uv[..., 1].max() <= 1.0
