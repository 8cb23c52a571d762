"""The scene schema (docs/model.md §1; wooddecay.scene.schema): every key documented, defaults valid."""
from __future__ import annotations

from wooddecay import scene as P


def test_schema_keys_unique_across_tissue_sections():
    seen = set()
    for sec in P.TISSUE_SECTIONS:
        for name in P.PARAMS[sec]:
            assert name not in seen
            seen.add(name)
    assert set(P.TISSUE_KEYS) == seen


def test_schema_defaults_validate_and_have_docs():
    for sec, table in P.PARAMS.items():
        for name, p in table.items():
            assert p.section == sec and p.name == name
            assert p.doc and "\n" not in p.doc
            if p.default is not None:
                assert P.validate_value(p, p.default, "x") == p.default
    assert "alpha_w0" in P.describe()


def test_table3_symbols_present():
    for key in ["fungi.alpha_w0", "fungi.D_b", "moisture.k_DM", "mechanics.M_0", "mechanics.S", "mechanics.s",
                "mechanics.p_l_bend", "mechanics.k_c", "mechanics.k_l", "mechanics.k_col", "mechanics.mu_f"]:
        P.get_param(key)
    assert P.get_param("fungi.alpha_w0").unit == "1/day"
    # SI units need a stiffer contact than Table 3's 30 N/m^2 (docs/decisions.md); the doc says so
    assert P.get_param("mechanics.k_col").default == 1e7 and "30" in P.get_param("mechanics.k_col").doc
