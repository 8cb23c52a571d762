"""TreeQSM cylinder tables as skeletons (docs/model.md §1)."""
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wooddecay.errors import InputError
from wooddecay.strands.qsm import load_treeqsm
from wooddecay.strands.skeleton_loader import load_skeleton

# A trunk cylinder (1) with a continuation (2) and a branch (3) starting half way up cylinder 2.
TABLE = """# start_xyz axis_xyz length radius parent
start_x,start_y,start_z,axis_x,axis_y,axis_z,length,radius,parent
0, 0, 0,   0, 0, 1,   1.0, 0.20, 0
0, 0, 1,   0, 0, 2,   1.0, 0.15, 1   # axis need not be unit length
0, 0, 1.5, 0.6, 0, 0.8, 0.5, 0.05, 2
"""


def write(tmp_path, text, name="tree.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_round_trip_three_cylinders(tmp_path):
    sk = load_treeqsm(write(tmp_path, TABLE))
    assert sk.ids == ("c1_base", "c1", "c2", "c3")
    assert sk.parent.tolist() == [-1, 0, 1, 2]
    expected = [[0, 0, 0], [0, 0, 1], [0, 0, 2], [0.3, 0, 1.9]]
    np.testing.assert_allclose(sk.positions, expected, atol=1e-15)
    radii = [p.param("radius") for p in sk.profiles]
    assert radii == [0.20, 0.20, 0.15, 0.05]
    assert all(p.kind == "circle" for p in sk.profiles)
    assert not sk.anchored.any()
    assert sk.source == str(tmp_path / "tree.csv")


def test_whitespace_and_tabs_and_parents_listed_after_children(tmp_path):
    text = "0 0 1 0 0 1 1 0.1 2\n0\t0\t0\t0\t0\t1\t1\t0.2\t0\n"
    sk = load_treeqsm(write(tmp_path, text, "tree.txt"))
    assert sk.ids == ("c2_base", "c2", "c1")
    assert sk.parent.tolist() == [-1, 0, 1]
    np.testing.assert_allclose(sk.positions[-1], [0, 0, 2])


def test_load_skeleton_dispatches_treeqsm_with_scale(tmp_path):
    write(tmp_path, TABLE)
    sk = load_skeleton({"file": "tree.csv", "scale": 0.5}, tmp_path, "scene.toml")
    np.testing.assert_allclose(sk.positions[2], [0, 0, 1.0])
    assert sk.profiles[0].param("radius") == pytest.approx(0.1)


@pytest.mark.parametrize(
    "row, message",
    [
        ("0,0,0,0,0,1,1,abc,0", "radius must be a number"),
        ("0,0,0,0,0,1,1,0.1", "has 8 columns; expected 9"),
        ("0,0,0,0,0,1,1,0.1,7", "parent must be a cylinder index 1..3"),
        ("0,0,0,0,0,1,1,0.1,2", "other than its own"),
        ("0,0,0,0,0,1,1,0.1,1.5", "parent must be a cylinder index"),
        ("0,0,0,0,0,1,1,-0.1,0", "radius must be > 0 m"),
        ("0,0,0,0,0,1,0,0.1,0", "length must be >= 1e-09 m"),
        ("0,0,nan,0,0,1,1,0.1,0", "start_z must be a finite number"),
        ("0,0,0,0,0,inf,1,0.1,0", "axis_z must be a finite number"),
        ("0,0,0,0,0,0,1,0.1,0", "axis must be a non-zero finite vector"),
    ],
)
def test_rejections_name_the_line(tmp_path, row, message):
    text = "0,0,0,0,0,1,1,0.2,0\n# comment\n" + row + "\n0,0,1,0,0,1,1,0.1,1\n"
    path = write(tmp_path, text)
    with pytest.raises(InputError) as info:
        load_treeqsm(path)
    assert str(info.value).startswith(f"{path}: line 3: ")
    assert message in str(info.value)


def test_reject_parent_cycle(tmp_path):
    text = "0,0,0,0,0,1,1,0.2,0\n0,0,1,0,0,1,1,0.1,3\n0,0,2,0,0,1,1,0.1,2\n"
    with pytest.raises(InputError, match=r"line 2: parent cylinders form a cycle 2 -> 3 -> 2"):
        load_treeqsm(write(tmp_path, text))


def test_reject_zero_length_edge_between_cylinder_ends(tmp_path):
    text = "0,0,0,0,0,1,1,0.2,0\n0,0,0.5,0,0,1,0.5,0.1,1\n"
    with pytest.raises(InputError, match=r"line 2: .*zero-length edge"):
        load_treeqsm(write(tmp_path, text))


def test_first_row_with_a_typo_is_not_taken_for_a_header(tmp_path):
    with pytest.raises(InputError, match=r"line 1: start_z must be a number \(got '0..1'\)"):
        load_treeqsm(write(tmp_path, "0,0,0..1,0,0,1,1,0.2,0\n0,0,1,0,0,1,1,0.1,1\n"))


def test_reject_empty_and_binary_files(tmp_path):
    with pytest.raises(InputError, match="no cylinders found"):
        load_treeqsm(write(tmp_path, "# nothing\n\n"))
    path = tmp_path / "bin.csv"
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(InputError, match="not UTF-8"):
        load_treeqsm(path)
    with pytest.raises(InputError, match="cannot read"):
        load_treeqsm(tmp_path)


numbers = st.one_of(
    st.integers(-3, 5).map(str), st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["0", "1", "0.1", "-1", "nan", "inf", "1e400", "x", "", "#", "1,5"]),
)
rows = st.lists(numbers, min_size=0, max_size=11).map(lambda cells: ",".join(cells))
tables = st.lists(st.one_of(rows, rows.map(lambda r: r.replace(",", " "))), max_size=6).map("\n".join)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(content=st.one_of(st.binary(max_size=200), st.text(max_size=200), tables))
def test_fuzz_treeqsm_only_input_error(tmp_path, content):
    path = tmp_path / "t.csv"  # overwritten by every example
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8", errors="surrogatepass")
    try:
        sk = load_treeqsm(path)
    except InputError as err:
        assert "\n" not in str(err)
    else:
        assert len(sk.ids) == len(sk.positions) >= 2
