"""The scene schema: every key of every scene table, its default, unit, allowed range and doc.

This module is the single source of truth for what a scene may contain (docs/model.md §1). Every
parameter of the paper's Table 3 (woodstock) is a key named after its symbol (``alpha_w0``,
``D_b``, ``k_DM``, ``M_0``, ``S``, ``s``, ``p_l_*``, ``k_c``, ``k_l``, ``k_col``, ``mu_f``, ...)
with the Table 3 typical value as its default. Units are SI; biology time is in days, mechanics
time in seconds, moisture in kg/kg.

Two kinds of table, one row format ``(name, default, unit, range, doc[, kind])``:

* scalar sections (``[strands]``, ``[fungi]``, ...): :data:`PARAMS` ``{section: {name: Param}}``
  from :data:`_SCHEMA`. Parameters of :data:`TISSUE_SECTIONS` may be overridden per tissue
  (``[tissue.heartwood]``); their names are unique across those sections (asserted below) so a
  tissue table uses bare names (:data:`TISSUE_KEYS`).
* entry tables (``[[inoculation]]``, ``[[load]]``, ``[[collider]]`` and the ``region`` table of
  the first two): :data:`TABLES` ``{name: Table}`` from :data:`_TABLE_SCHEMA`. A key without a
  default is required. A table with a ``kind`` key has further keys per kind: a region is a
  ``box`` (``min``, ``max``), ``sphere`` (``center``, ``radius``), skeleton ``node`` (``id``,
  ``radius``), log ``end`` (``which``, ``depth``) or bark ``wound`` (``position``, ``radius``,
  ``depth``), in ``world`` or wood-local (r, phi, s) coordinates (docs/model.md §3 inoculation); a
  collider (woodstock §5.1) is a ``plane``, ``box``, ``sphere`` or ``cylinder``.

``[scene] format`` is the version of the scene file format (:data:`FORMAT`; a file without it is
format 1, one of a newer format is refused, docs/scene.md "Format version").

:func:`format_range` says in words what a :class:`Param` allows (``(0, 1] m``), :func:`default_text`
its default; :func:`describe` prints the scalar sections as Markdown, and
:func:`wooddecay.scene.docs.scene_docs` every table as docs/scene.md.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from wooddecay.errors import format_value
from wooddecay.wood import DAYS_PER_YEAR


@dataclass(frozen=True)
class Param:
    """One scene parameter.

    ``lo``/``hi`` are ``None`` when unbounded; ``lo_open``/``hi_open`` say whether the bound itself
    is excluded. ``kind`` is one of ``float``, ``int``, ``bool``, ``str``, ``enum``, ``vec3``,
    ``list`` (the moisture schedule), ``seasons`` (the climate's keyframes), ``interval`` (``[start, end]`` days), ``region`` (a nested
    region table) or ``node_id`` (a skeleton node); ``choices`` lists the values of an ``enum``.
    ``default`` is ``None`` for a derived default in a scalar section (``scene.name``: the scene
    file stem; ``strands.connect_radius``: ``2.5 * r_s``) and for a required key of an entry table.
    """

    section: str
    name: str
    default: Any
    unit: str
    lo: float | None
    hi: float | None
    lo_open: bool
    hi_open: bool
    kind: str
    doc: str
    choices: tuple[str, ...] = ()

    @property
    def key(self) -> str:
        """Dotted key, e.g. ``strands.r_s``."""
        return f"{self.section}.{self.name}"


@dataclass(frozen=True)
class Table:
    """The keys of an entry table (``[[inoculation]]``, ``[[load]]``, ``[[collider]]``, ``region``).

    ``keys`` holds the keys of every entry in order; a table with a ``kind`` key lists each kind's
    further keys in ``kinds`` (empty otherwise). A key whose default is ``None`` is required.
    """

    name: str
    keys: dict[str, Param]
    kinds: dict[str, dict[str, Param]]

    def keys_of(self, kind: str | None) -> dict[str, Param]:
        """The keys of an entry of ``kind`` (``None`` for a table without kinds), in order."""
        return self.keys if kind is None else {**self.keys, **self.kinds[kind]}


# ---------------------------------------------------------------------------------------------
# The compact literal. Row: (name, default, unit, range, doc[, kind]).
# range: "(lo, hi]" style interval ("inf" for unbounded), "any", or "" (no numeric range).
# kind is inferred from the default (bool/int/float/str) unless given: "float" (derived default),
# "enum:a|b", "vec3", "list", "interval", "region", "node_id".
# ---------------------------------------------------------------------------------------------
_T3 = "woodstock Table 3"
#: The scene file format this wooddecay writes and the range it reads (``[scene] format``). A change
#: to what a scene file means (a key renamed, removed or reinterpreted, a default changed) bumps
#: FORMAT and is listed in CHANGELOG.md; a scene that declares a newer format is refused
#: (:func:`wooddecay.scene.validate.check_format`). A file without the key was written before it
#: existed: format 1 (:data:`FORMAT_UNDECLARED`), whatever FORMAT is by then.
FORMAT = 1
FORMAT_MIN = 1
FORMAT_UNDECLARED = 1
_SCHEMA: dict[str, list[tuple]] = {
    "scene": [
        ("format", FORMAT_UNDECLARED, "", f"[{FORMAT_MIN}, {FORMAT}]", f"Version of the scene file format (CHANGELOG.md): a file without it is read as format {FORMAT_UNDECLARED}; one that declares a newer format than this wooddecay reads is refused. It says how the file is read, not what is simulated, so it is not part of the scene hash."),
        ("name", None, "", "", "Scene name used for output files and the USD prim; default: the scene file stem.", "str"),
        ("seed", 0, "", "[0, inf)", "Seed of the numpy Generator that drives every random choice (packing, rings, noise, BSP)."),
        ("quality", "final", "", "", "Quality preset: 'draft' multiplies strands.r_s, strands.rod_length (and connect_radius) by 1.5 after validation.", "enum:draft|final"),
        ("description", "", "", "", "Free text describing the scene; the stage carries it as its root layer's documentation, the glTF as asset.extras.description."),
    ],
    "strands": [
        ("r_s", 0.006, "m", "(0, 1]", f"Strand radius r_s (docs/model.md §2); also the capsule radius r_i of contact, {_T3} typical [0.005, 0.05] m."),
        ("phi_pack", 0.8, "", "(0, 0.9]", "Packing fraction: strands per profile = floor(phi_pack * area / (pi r_s^2)) (docs/model.md §2)."),
        ("rod_length", 0.04, "m", "(0, 10]", "Target rod element length along a strand (randomly phased per strand; docs/model.md §2)."),
        ("connect_radius", None, "m", "(0, 10]", "REG edge radius: segments of different strands closer than this are joined (woodstock §5); default 2.5 * r_s, must be >= 2 * r_s.", "float"),
        ("packing_iterations", 200, "", "[1, 100000]", "PBD iterations when packing strand positions on a profile (docs/model.md §2)."),
        ("transport_reach", 4.0, "r_s", "[2, 20]", "Transverse reach of the transport graph in strand radii: cross-strand pairs within reach * r_s exchange fields (a wider ring than the REG so that positive weights can represent a_r != a_t at any lattice orientation; docs/decisions.md)."),
    ],
    "rings": [
        ("ring_width", 0.004, "m", "(0, 0.5]", "Mean growth-ring width (woodification §4.1)."),
        ("weibull_c", 2.0, "", "(0, 10]", "Weibull shape c of the growth rate s(t) = c t^(c-1) exp(-t^c) (woodification §4.1)."),
        ("eccentricity", 0.0, "", "[-0.9, 0.9]", "Reaction-wood eccentricity e (woodification Eq. 3): rings wider where n . y_hat > 0 for e > 0."),
        ("width_noise", 0.2, "", "[0, 0.9]", "Relative per-year noise on ring widths (woodification §4.2)."),
        ("pith_blend", 0.3, "", "[0, 1]", "Blend of the innermost rings towards a near-circular pith contour (branch-fracture §3.3)."),
        ("bark_thickness", 0.008, "m", "[0, 1]", "Bark tissue: elements with bark distance bd below this (docs/model.md §2)."),
        ("sapwood_rings", 8, "", "[0, 10000]", "Number of outermost rings that are sapwood (docs/model.md §2)."),
        ("pith_rings", 1, "", "[0, 10000]", "Number of innermost rings that are pith (docs/model.md §2)."),
    ],
    "bsp": [
        ("cells", 800, "", "[0, 10000000]", f"Total BSP leaves over the whole model (woodstock §7.1, Fig. 11; {_T3} 'BSP size/depth'); with fewer cells than branches each branch is one leaf; 0 disables prepartitioning (one leaf, theta = 0)."),
        ("elongation", 1.0, "", "[0.01, 100]", "Stretch of BSP cells along e_l (woodstock Fig. 11b uses 2.5)."),
        ("jitter", 0.2, "", "[0, 0.45]", "Random offset of each BSP split from the middle, as a fraction of the cell extent (woodstock §7.1)."),
    ],
    "weakpoints": [
        ("k_W", 0.3, "", "[0, 1)", f"Weak-point gain: rates scale by (1 + k_W (2W - 1)) (woodstock §6, Fig. 5; {_T3} W(x))."),
        ("scale", 0.05, "m", "(0, 1000]", "Perlin noise feature size of W(x) in wood-local coordinates (woodstock Fig. 5)."),
        ("stretch", 4.0, "", "[1, 1000]", "Stretch of the noise along the grain e_l (woodstock Fig. 5)."),
        ("octaves", 3, "", "[1, 8]", "Perlin noise octaves of W(x)."),
        ("junction_boost", 0.3, "", "[0, 1]", "Rise of W near branch junctions (woodstock Fig. 5: weak regions around junctions)."),
        ("junction_radius", 0.1, "m", "(0, 1000]", "Distance over which the junction boost fades."),
    ],
    "transport": [
        ("a_r", 0.25, "", "(0, 1000]", f"Radial diffusivity factor: D_r = D a_r (woodstock Fig. 5; {_T3} e_r)."),
        ("a_t", 1.0, "", "(0, 1000]", f"Tangential diffusivity factor: D_t = D a_t (woodstock Fig. 5; {_T3} e_t)."),
        ("a_l", 4.0, "", "(0, 1000]", f"Longitudinal (grain) diffusivity factor: D_l = D a_l (woodstock Fig. 5; {_T3} e_l)."),
    ],
    "fungi": [
        ("alpha_w0", 5e-3, "1/day", "[0, 10]", f"Baseline white-rot growth rate alpha_w0 (Eqs. 8, 10; {_T3} typical [1e-4, 1e-2])."),
        ("alpha_b0", 5e-3, "1/day", "[0, 10]", f"Baseline brown-rot growth rate alpha_b0 (Eqs. 9, 10; {_T3} typical [1e-4, 1e-2])."),
        ("D_w", 1e-6, "m^2/day", "[0, 1e-2]", f"White-rot diffusion coefficient D_w (Eq. 8; {_T3} typical [1e-7, 1e-5])."),
        ("D_b", 1e-6, "m^2/day", "[0, 1e-2]", f"Brown-rot diffusion coefficient D_b (Eq. 9; {_T3} typical [1e-7, 1e-5])."),
        ("lambda_l", 0.5, "", "[0, 10]", f"Weight of lignin availability in white-rot growth lambda_l (Eq. 8; {_T3} typical 0.5)."),
        ("lambda_c", 0.5, "", "[0, 10]", f"Weight of carbohydrate availability in white-rot growth lambda_c (Eq. 8; {_T3} typical 0.5)."),
        ("K_c", 0.2, "", "(0, 10]", f"Half-saturation of carbohydrate accessibility K_c (Eq. 8; {_T3} typical 0.2)."),
        ("beta_w", 1e-3, "1/day", "[0, 10]", f"Defense inhibition of white rot beta_w (Eq. 8; {_T3} typical [1e-4, 1e-2])."),
        ("beta_b", 1e-3, "1/day", "[0, 10]", f"Defense inhibition of brown rot beta_b (Eq. 9; {_T3} typical [1e-4, 1e-2])."),
        ("gamma_cw", 5e-3, "1/day", "[0, 10]", f"Carbohydrate depletion by white rot gamma_cw (Eq. 12; {_T3} typical [1e-4, 1e-2])."),
        ("gamma_cb", 5e-3, "1/day", "[0, 10]", f"Carbohydrate depletion by brown rot gamma_cb (Eq. 12; {_T3} typical [1e-4, 1e-2])."),
        ("gamma_lw", 5e-3, "1/day", "[0, 10]", f"Lignin depletion by white rot gamma_lw (Eq. 13; {_T3} typical [1e-4, 1e-2])."),
        ("rho_c", 1e-4, "1/day", "[0, 10]", f"Defense-driven carbohydrate recovery rho_c (Eq. 12; {_T3} typical [1e-5, 1e-3])."),
        ("rho_l", 1e-4, "1/day", "[0, 10]", f"Defense-driven lignin recovery rho_l (Eq. 13; {_T3} typical [1e-5, 1e-3])."),
        ("kappa", 1e-3, "1/day", "[0, 10]", f"Defense induction gain kappa (Eq. 14; {_T3} typical [1e-4, 1e-2])."),
        ("delta", 1e-5, "1/day", "[0, 10]", f"Defense decay rate delta (Eq. 14; {_T3} typical [1e-6, 1e-4])."),
        ("D_C", 1e-6, "m^2/day", "[0, 1e-2]", f"Defense diffusion coefficient D_C (Eq. 14; {_T3} typical [1e-7, 1e-5])."),
        ("M_min", 0.2, "kg/kg", "[0, 10]", f"Lower end of the moisture window for fungal growth M_min (Eq. 10; {_T3} typical 0.2)."),
        ("M_max", 0.9, "kg/kg", "[0, 10]", f"Upper end of the moisture window for fungal growth M_max (Eq. 10; {_T3} typical 0.9)."),
        ("s_t", 0.05, "kg/kg", "(0, 10]", f"Smoothstep width of the moisture window s_t (Eqs. 10-11; {_T3} typical 0.05)."),
    ],
    "moisture": [
        ("M_1", 1.0, "kg/kg", "(0, 10]", f"Maximum admissible moisture M_1 (Eq. 15; {_T3} typical 1.0)."),
        ("M_2", 0.1, "kg/kg", "[0, 10]", f"Minimum admissible moisture M_2 (Eq. 15; {_T3} typical 0.1)."),
        ("M_init", 0.5, "kg/kg", "[0, 10]", "Initial moisture content of every element; must lie in [M_2, M_1]."),
        ("D_M0", 1e-5, "m^2/day", "[0, 1e-2]", f"Baseline moisture diffusivity D_M0 (Eq. 20; {_T3} typical [1e-6, 1e-4])."),
        ("k_DM", 0.5, "", "[0, 10]", f"Sensitivity of D_M to health loss k_DM (Eq. 20; {_T3} typical [0, 1])."),
        ("k_H", 2.5, "", "[0, 100]", "Carbohydrate weight k in the health aggregate H = (H_l + k H_c) / (1 + k) (Eq. 20, §9.4; docs/model.md §3)."),
        ("k_in0", 0.01, "1/day", "[0, 100]", f"Moisture uptake rate k_in0 in k_in = k_in0 max(0, 1 - k_r_in bd) H_c (Eq. 15; {_T3} k_in)."),
        ("k_r_in", 10.0, "1/m", "[0, 1000000]", "Decay of uptake with bark distance k_r_in (Eq. 15)."),
        ("k_out0", 0.2, "1/(day m)", "[0, 10000]", f"Moisture loss rate k_out0 (per metre of depth bd_0 - bd) in k_out = k_out0 max(0, 1 - k_r_out H_c) max(0, bd_0 - bd) (Eq. 15; {_T3} k_out)."),
        ("k_r_out", 0.5, "", "[0, 100]", "Reduction of moisture loss by carbohydrate health k_r_out (Eq. 15)."),
        ("bd_0", 0.05, "m", "[0, 100]", f"Bark-distance depth of moisture loss bd_0 (Eq. 15; {_T3} bd(x))."),
        ("schedule", [], "", "", "Seasonal keyframes [[day, M_1, M_2], ...] replacing M_1, M_2 over time (docs/model.md §3); days strictly increasing, M_2 < M_1.", "list"),
    ],
    "climate": [
        ("preset", "temperate", "", "", "Climate that wets and dries the wood through Eq. 15 (sim/climate.py): 'temperate' (wet winters, summers that dry the surface below M_0), 'dry' (the wood dries out), 'wet-ground' (a forest floor), 'constant' (Table 3's Eq. 15 unchanged, no ground wetting).", "enum:temperate|dry|wet-ground|constant"),
        ("seasons", [], "", "", "Keyframes [[day_of_year, w_in, w_out, w_ground], ...] replacing the preset's: factors on k_in0, k_out0 and k_ground, linear between keyframes and repeated every year (day 0 = 1 January).", "seasons"),
        ("start_day", 0.0, "day", "[0, 365.25)", "Day of the year on which the bake begins (0 = 1 January): a log felled in winter starts wet, a board sawn in May dries through its first summer."),
        ("k_ground", 0.05, "1/day", "[0, 100]", "Uptake towards M_1 where the wood touches the ground (Eq. 15's k_in gains w_ground k_ground there): logs rot from below."),
        ("ground_depth", 0.01, "m", "[0, 10]", "An element touches the ground when its lowest point is within this of the ground plane ([mechanics] ground_height), at the rods' current positions."),
    ],
    "wood": [
        ("H_c_init", 1.0, "", "[0, 1]", f"Initial carbohydrate health H_c ({_T3})."),
        ("H_l_init", 1.0, "", "[0, 1]", f"Initial lignin health H_l ({_T3})."),
        ("C_init", 0.0, "", "[0, 1]", f"Initial defense efficacy C ({_T3}, Eq. 14)."),
        ("species", "none", "", "", "Wood species whose orthotropic moduli (E_L, E_R, E_T, G_LR, G_LT, G_RT at 12% moisture, with sources: wooddecay/species.py, docs/model.md §4 \"Species moduli\") the converged bundle takes as its homogenised stiffness, and whose density becomes mechanics.rho_dry: the strands' E and G and the REG connection's stiffness along R, T and L and across it are calibrated to them (benchmarks/moduli.py). Needs mechanics.solver = 'implicit' and leaves mechanics.E, G, rho_dry and connection_shear to the species. 'none': the paper's isotropic mechanics.E and G.", "enum:none|oak|beech|pine|spruce|birch"),
    ],
    "mechanics": [
        ("M_0", 0.2, "kg/kg", "[0, 10]", f"Drying threshold M_0 below which shrinkage and limit reduction start (Eqs. 16-17; {_T3} typical 0.2)."),
        ("S", 0.5, "1/(kg/kg)", "[0, 10]", f"Shrinkage gain of REG rest offsets S (Eq. 16; {_T3} typical [0, 1])."),
        ("s", 0.02, "1/(kg/kg)", "[0, 1]", f"Shrinkage gain of rod rest length s (Eq. 17; {_T3} typical [0, 0.05])."),
        ("S_c", 0.0, "", "[0, 0.9]", "Brown-rot shrinkage: the linear shrinkage of wood that has lost all its carbohydrates. Its rest length (Eq. 17), its REG rest offsets (Eq. 16, pair means), its contact radius and its meshlet scale by 1 - S_c (1 - H_c), so brown-rotted cubes shrink and their pile settles lower (woodstock §3: the removal of carbohydrates makes the wood shrink; Fig. 12; docs/decisions.md, \"Brown rot shrinks\"). 0: Eqs. 16-17 as printed."),
        ("S_R", 1.0, "", "[0, 10]", "Radial shrinkage weight: a REG offset shrinks by (M_0 - M)^+ (S (S_R n_r^2 + S_T n_t^2) + s n_l^2) (Eq. 16; woodstock Table 2, Fig. 6; along the grain the strands' s, docs/decisions.md)."),
        ("S_T", 1.0, "", "[0, 10]", "Tangential shrinkage weight in Eq. 16 (woodstock Table 2, Fig. 6)."),
        ("L_0_stretch", 0.01, "", "[0, 10]", f"Baseline stretch strain limit L_0 (Eq. 18; {_T3} L_0)."),
        ("L_0_shear", 0.05, "", "[0, 10]", f"Baseline shear strain limit L_0 (Eq. 18; {_T3} L_0)."),
        ("L_0_bend", 0.1, "", "[0, 10]", f"Baseline bend strain limit L_0 (Eq. 18; {_T3} L_0)."),
        ("L_0_twist", 0.1, "", "[0, 10]", f"Baseline twist strain limit L_0 (Eq. 18; {_T3} L_0)."),
        ("L_0_bundle", 0.02, "", "[0, 10]", f"Baseline bundle (REG connection) strain limit L_0 (Eq. 18; {_T3} L_0)."),
        ("L_knee", 0.0, "", "[0, 1]", "Where Eq. 19's limits reach L_0: at M_0 + L_knee (M_1 - M_0), so 0 (default) puts the knee at M_0, where §7 says reduced strain capacity starts (wood at or above M_0 keeps L_0), and 1 at M_1, Eq. 19 as printed (docs/decisions.md, \"Limits reduce below M_0\")."),
        ("p_l_stretch", 4.0, "", "[0.1, 20]", f"Exponent p_l of the moisture-to-limit map for stretch (Eq. 19; {_T3} typical [3, 5])."),
        ("p_l_shear", 4.0, "", "[0.1, 20]", f"Exponent p_l for shear (Eq. 19; {_T3} typical [3, 5])."),
        ("p_l_bend", 4.0, "", "[0.1, 20]", f"Exponent p_l for bend (Eq. 19; {_T3} typical [3, 5])."),
        ("p_l_twist", 4.0, "", "[0.1, 20]", f"Exponent p_l for twist (Eq. 19; {_T3} typical [3, 5])."),
        ("p_l_bundle", 4.0, "", "[0.1, 20]", f"Exponent p_l for bundle connections (Eq. 19; {_T3} typical [3, 5])."),
        ("k_c", 1.0, "", "[0, 100]", f"Integrity loss gain from carbohydrate depletion k_c (Eq. 21; {_T3} typical 1)."),
        ("k_l", 1.0, "", "[0, 100]", f"Integrity loss gain from lignin depletion k_l (Eq. 21; {_T3} typical 1)."),
        ("I_fail", 0.25, "", "[0, 1]", "Separation from decay: a REG connection or strand link whose integrity I_ij (Eq. 21) falls below this fails, so brown rot's carbohydrate loss separates the BSP cells (theta = 1) into blocks and white rot's lignin loss frays the wood everywhere (woodstock §7.1, Figs. 7-8; docs/decisions.md). 0: integrity only scales stiffness and limits."),
        ("m_crumble", 0.15, "", "[0, 1]", "An element whose remaining mass fraction (H_l + k H_c) / (1 + k) (§9.4) falls below this crumbles: its connections and strand links fail, it leaves contact and its meshlet dwindles from twice this fraction to nothing, so consumed wood (white rot's heartwood) leaves a cavity. Brown rot leaves its lignin (1 / (1 + k) = 0.29) and does not crumble. 0: never."),
        ("k_col", 1e7, "N/m^2", "[0, 1e12]", f"Penalty contact stiffness k_col (Eq. 4; {_T3} gives 30, which in SI units lets a 2 g element sink 2 cm into the ground; a piece resting on few contacts sinks sqrt(F / k_col): 0.75 kg on two pairs needs 1e7 to stay within 0.1 r_s; docs/decisions.md)."),
        ("v_depenetration", 0.1, "m/s", "(0, 1e6]", "Largest speed at which contact pushes out an overlap two capsules had when their pieces separated (shrinkage or a deformation brought them closer than at rest), and a particle's collider penetration older than the substep: they part at this speed instead of exploding, while a new or loaded penetration is resolved at once (docs/decisions.md)."),
        ("mu_f", 0.7, "", "[0, 2]", f"Friction coefficient mu_f (Eq. 7; {_T3} typical [0.5, 1.0])."),
        ("epsilon", 1e-4, "m/s", "(0, 1]", f"Velocity floor epsilon in the friction update (Eq. 7; {_T3})."),
        ("dt_mech", 1e-4, "s", "(0, 1]", f"Mechanics (XPBD) step dt_mech (Eq. 1; {_T3} gives 0.01, at which two iterations leave 10% strains in a resting log, above every strain limit; small steps of one iteration squash a resting log 0.2% instead of 2.5% at dt 1 ms with two; docs/decisions.md)."),
        ("N_mech", 25, "", "[1, 10000]", f"Mechanics substeps per macro step N_mech (Algorithm 1; {_T3} typical 25)."),
        ("strand_solver", "auto", "", "", "Stage 1 along each strand: 'gauss-seidel' projects the stretch, shear and bend-twist constraints one colour class at a time (a lone strand of many elements sags too far); 'direct' solves each unbroken run of a strand's elements together (block tridiagonal, Deul et al. 2018), so a lone strand is as stiff as E and G say at any element count, at 8x the cost of Stage 1; 'auto' solves directly the runs no intact REG edge ties to another strand (a lone strand, a stick broken free) and the bundled ones by Gauss-Seidel, where Stage 2 limits the stiffness (docs/decisions.md).", "enum:auto|gauss-seidel|direct"),
        ("solver", "xpbd", "", "", "The rods' solver: 'xpbd' projects the constraints (the paper's method, woodstock §5; one sweep a substep leaves a bundle softer than E and G say); 'implicit' takes backward Euler steps of the same energies by Newton's method to an equilibrium residual of residual_tolerance, settling by a static solve (docs/decisions.md, \"Implicit step\").", "enum:xpbd|implicit"),
        ("residual_tolerance", 0.01, "", "(0, 1]", "The equilibrium residual every implicit step is solved to (sim/equilibrium.py: net force and torque on the bound wood over its loads); 'wooddecay chart solver' charts the residual a bake reaches against its wall time (docs/decisions.md, \"Solver chart\")."),
        ("connection_shear", 0.0, "", "[0, 1]", "Stiffness of a REG connection across its rest direction as a fraction of its stiffness k_conn along it, with mechanics.solver = 'implicit': the fraction s of k_conn becomes a spring on the whole offset between the two centres, co-rotated with the pair (sim/equilibrium.py), the rest stays the paper's central spring (Eq. 2). 0 is the paper's connection, which lets an element held by one or two connections swing about its partner's centre (docs/decisions.md, \"Connection shear\")."),
        ("iterations", 1, "", "[1, 1000]", "XPBD constraint iterations per substep (Algorithm 1); substeps converge better than iterations at the same cost (docs/decisions.md)."),
        ("settle", 0.2, "s", "[0, 100]", "Seconds the rods settle under gravity at the start, with failure off and damping settle_damping; the strains they settle into are the reference failure strains are measured from (docs/decisions.md)."),
        ("settle_damping", 20.0, "1/s", "[0, 10000]", "Viscous damping while settling (about critical for the sway of a branch)."),
        ("E", 1e9, "Pa", "(0, 1e13]", "Young's modulus of a strand (stretch and bend compliance from E A, E I; docs/model.md §4)."),
        ("G", 4e8, "Pa", "(0, 1e13]", "Shear modulus of a strand (shear and twist compliance from G A, G J; docs/model.md §4)."),
        ("rho_dry", 450.0, "kg/m^3", "(0, 1e5]", "Dry wood density; element mass = rho_dry (1 + M) pi r_s^2 l (docs/model.md §2)."),
        ("gravity", [0.0, 0.0, -9.81], "m/s^2", "", "Gravity vector (world frame, Z up); any finite components (woodstock §5.4).", "vec3"),
        ("inertia_scale", 100.0, "", "[1, 1e6]", "Rotary inertia of a rod element over its physical m (r^2/4 + l^2/12). Euler-Bernoulli strands neglect rotary inertia; a larger one lets XPBD's stretch-shear projection move the particles rather than the orientation, which converges bending many times faster (docs/decisions.md)."),
        ("damping", 2.0, "1/s", "[0, 1000]", "Viscous velocity damping c: v <- v exp(-c dt) each substep, so pieces come to rest (woodstock §5.4)."),
        ("sleep_speed", 5e-4, "m/s", "[0, 1]", "A piece whose particles all moved slower than this over sleep_time is taken out of the solve until a failure, new masses, a load or an impact wakes it (sim/sleep.py): an iterative contact solver otherwise keeps a resting pile jittering at ~1e-3 m/s. 0: never sleep (docs/decisions.md)."),
        ("sleep_time", 0.2, "s", "(0, 100]", "Window over which sleep_speed is measured (sim/sleep.py)."),
        ("ground", True, "", "", "Ground plane collider at z = ground_height (woodstock §5.1 colliders)."),
        ("ground_height", 0.0, "m", "any", "Height of the ground plane."),
        ("clamp_depth", 0.05, "m", "(0, 10]", "Depth of the clamp at an anchored root: every strand of its tree that starts before the plane this far along the wood from the root (distance to the root along the skeleton) gets a particle on that plane, held with the wood before it; beyond it the wood is free (docs/model.md §7)."),
    ],
    "time": [
        ("days", 365.0, "day", "[0, 1e6]", "Simulated biological time."),
        ("years", 0.0, "year", "[0, 2700]", f"Simulated time in years of {DAYS_PER_YEAR} days; when > 0 it sets days (a scene gives one of the two, or both equal)."),
        ("dt_bio", 0.5, "day", "(0, 1e4]", f"Biophysics macro step dt_bio (Algorithm 1; {_T3} typical 0.5)."),
        ("frames", 24, "", "[1, 100000]", "Number of output frames over the simulated time."),
        ("fps", 24.0, "1/s", "(0, 1000]", "Playback frame rate of the exported animation (USD timeCodesPerSecond)."),
        ("schedule", "adaptive", "", "", "'adaptive': mechanics runs only when the rest data, integrity, masses or loads changed past the tolerances below or something fails, and then until the wood is quiet (sim/schedule.py); 'fixed': N_mech substeps every macro step (Algorithm 1).", "enum:adaptive|fixed"),
        ("strain_tolerance", 1e-4, "", "(0, 1]", "Adaptive schedule: a rest length or REG offset strain change since the last mechanics solve that triggers one."),
        ("tolerance", 0.02, "", "(0, 1]", "Adaptive schedule: an integrity I_ij change, or a relative element mass change, since the last mechanics solve that triggers one."),
        ("rest_speed", 0.01, "m/s", "(0, 10]", "Adaptive schedule: mechanics goes on in chunks of N_mech substeps until a chunk splits no piece and no piece's centre of mass moved faster than this, on average or at its end; the first chunk of a solve that relaxes changed rest data is the fewest substeps that bring a piece falling from rest to 1.15x this speed (12 at the defaults, sim/schedule.py)."),
        ("hold_speed", 1e-3, "m/s", "[0, 10]", "Adaptive schedule: within a solve, a piece whose centre of mass moved slower than this over a chunk, on average and at its end, is held still for the next chunk (the kernels skip it) unless a moving piece pushes it; 0: never (sim/schedule.py, 'Held pieces'). At 0.01 coasting pieces are held too: the shipped log's five years simulate about 1.6x faster, but slow slides stop early (the tiny log's decayed blocks 1.1 cm down its sides instead of over 2; docs/decisions.md, 'Held pieces')."),
        ("max_mechanics", 0.05, "s", "(0, 1000]", "Adaptive schedule: most seconds of mechanics in one macro step; a piece still moving goes on in the next (0.05 s: 1.5 s of mechanics between the frames of a year of 24 frames at dt_bio 0.5 day)."),
    ],
    "bark": [
        ("species", "spruce", "", "", "Bark crack preset (woodification §5, Fig. 10): sets pattern, threshold, tip_gain and noise where they are not given: 'oak' long vertical fissures, 'spruce' and 'pine' a net of scaly plates, 'birch' horizontal bands, 'beech' smooth bark that rarely cracks.", "enum:spruce|pine|oak|birch|beech"),
        ("cracks", True, "", "", "Simulate bark cracks and shedding (sim/bark.py); false leaves the bark whole."),
        ("pattern", None, "", "", "Anisotropy of the crack stress (woodification Fig. 10): 'fissures' (circumferential tension: cracks along the grain), 'plates' (both directions: a net), 'bands' (tension along the grain: horizontal cracks), 'none' (isotropic); default from species.", "enum:fissures|plates|bands|none"),
        ("threshold", None, "", "(0, 10]", "Crack threshold: the largest principal tensile strain of a bark vertex's separation tensor above which it cracks (Iben and O'Brien 2006); default from species.", "float"),
        ("tip_gain", None, "", "[0, 100]", "Extra stress at crack tips as a factor on their separation (cracks grow rather than multiply, woodification §5); default from species.", "float"),
        ("noise", None, "", "[0, 0.9]", "Relative amplitude of the coherent noise on the threshold (where cracks start); default from species.", "float"),
        ("growth", 0.3, "", "[0, 100]", "Weight of the growth strain: the circumferential expansion recorded by the outer rings over the bark's life (woodification §4, Eqs. 2-3)."),
        ("drying", 1.0, "", "[0, 100]", "Weight of the drying strain of the bark: its shrinkage S (S_T, s) (M_0 - M)^+ on the wood beneath (woodstock Eq. 16)."),
        ("bark_years", 8, "year", "[1, 1000]", "Years of growth the outer bark has lived through (its growth strain is the outer rings' expansion over them)."),
        ("shadow", 0.02, "m", "(0, 1]", "Stress shadow of a crack: the bark's stress across a crack is relieved by exp(-d / shadow) at distance d from it (shear lag on the wood beneath), so cracks keep their distance."),
        ("spacing", 1.0, "r_s", "[0.25, 10]", "Edge length of the bark crack mesh in strand radii."),
        ("crack_width", 0.008, "m", "(0, 0.1]", "Width of a crack in its middle (it narrows to its tips, woodification §5)."),
        ("crack_depth", 1.0, "", "(0, 10]", "Crack depth at its middle as a multiple of its width, at most the bark thickness (V-shaped profile)."),
        ("groove_width", 0.0, "m", "[0, 0.1]", "Cracks wider than this are cut into the mesh as grooves (the bark vertices move in by the crack depth, wooddecay/export/bark_surface.py); 0 (the default): never, the crack map and the shader's bump draw them."),
        ("shedding", 0.2, "1/year", "[0, 100]", "Rate at which the bark's bond to the wood weakens with decay (1 - H) and wet/dry cycles (moisture change); a plate bounded by cracks falls when its bond is gone."),
        ("plate_area", 0.03, "m^2", "(0, 100]", "Largest piece of bark, bounded by cracks, that comes off as one plate."),
    ],
    "export": [
        ("usd", True, "", "", "Write the USD stage <name>.usdc."),
        ("gltf", True, "", "", "Write the glTF binary <name>.glb."),
        ("gltf_frame", -1, "", "any", "Frame exported to glTF; negative counts from the end (-1 = last)."),
        ("point_tolerance", 2e-4, "m", "(0, 0.1]", "A piece's points are written again at a frame only where the frame's points lie further than this from the last written ones carried by the piece's rigid motion (itself written as the piece's transform when it moved a point further than this); the same bound on bark_crack_depth (docs/architecture.md \"USD stage\")."),
        ("field_step", 2e-3, "", "(0, 1]", "H_c, H_l, M, R_w, R_b, C and bark_crack are written as indices into a table of values this far apart (indexed primvars), so a written value is off by at most half of it (a quarter of a step of an 8-bit colour); a piece's indices are written again only at a frame where one changed (docs/architecture.md \"USD stage\")."),
    ],
}

#: [bark] species presets: the keys a scene leaves out (woodification Fig. 10 patterns). Thresholds
#: are tensile strains of the separation tensor; the growth strain of the outer bark is 0.05-0.3.
BARK_SPECIES: dict[str, dict[str, Any]] = {
    "spruce": {"pattern": "plates", "threshold": 0.03, "tip_gain": 3.0, "noise": 0.4},
    "pine": {"pattern": "plates", "threshold": 0.04, "tip_gain": 2.5, "noise": 0.5},
    "oak": {"pattern": "fissures", "threshold": 0.02, "tip_gain": 4.0, "noise": 0.3},
    "birch": {"pattern": "bands", "threshold": 0.03, "tip_gain": 3.0, "noise": 0.4},
    "beech": {"pattern": "none", "threshold": 0.5, "tip_gain": 1.0, "noise": 0.2},
}

#: Factor applied to strand lengths (r_s, rod_length, connect_radius) by ``quality = "draft"``.
DRAFT_SCALE = 1.5
#: Default connect_radius in units of r_s, and the smallest allowed.
CONNECT_FACTOR = 2.5
CONNECT_MIN_FACTOR = 2.0

_VEC = "vec3"
_LENGTH = "(0, inf)"
#: Entry tables: ``{table: {"": common rows, kind: that kind's rows}}``; ``region`` is the
#: ``region`` key of [[inoculation]] and [[load]].
_TABLE_SCHEMA: dict[str, dict[str, list[tuple]]] = {
    "inoculation": {"": [
        ("fungus", None, "", "", "Fungus kind.", "enum:white|brown"),
        ("activity", 0.1, "", "(0, 1]", "Initial activity R_w or R_b (woodstock Eqs. 8-9)."),
        ("day", 0.0, "day", "[0, inf)", "Day the inoculation happens."),
        ("region", None, "", "", "Where the fungus starts (docs/model.md §3).", "region"),
    ]},
    "load": {"": [
        ("region", None, "", "", "Elements the force is applied to (docs/model.md §4, woodstock Fig. 17).", "region"),
        ("force", None, "N", "", "Force applied to the region.", _VEC),
        ("days", None, "day", "[0, inf)", "Day interval [start, end] the force acts over.", "interval"),
    ]},
    "region": {
        "": [
            ("kind", None, "", "", "Region kind.", "enum:box|sphere|node|end|wound"),
            ("space", "world", "", "", "Coordinates of the region: world, or wood-local (r, phi, s).", "enum:world|wood"),
        ],
        "box": [
            ("min", None, "m", "", "Lower corner; min < max componentwise.", _VEC),
            ("max", None, "m", "", "Upper corner.", _VEC),
        ],
        "sphere": [
            ("center", None, "m", "", "Centre.", _VEC),
            ("radius", None, "m", _LENGTH, "Radius.", "float"),
        ],
        "node": [
            ("id", None, "", "", "Id of a skeleton node.", "node_id"),
            ("radius", None, "m", _LENGTH, "Radius around the node.", "float"),
        ],
        "end": [
            ("which", "root", "", "", "Which log end.", "enum:root|tip"),
            ("depth", None, "m", _LENGTH, "Depth from the end along the log.", "float"),
        ],
        "wound": [
            ("position", None, "m", "", "Point on the bark.", _VEC),
            ("radius", None, "m", _LENGTH, "Radius of the wound.", "float"),
            ("depth", None, "m", _LENGTH, "Depth below the bark.", "float"),
        ],
    },
    "collider": {
        "": [("kind", None, "", "", "Collider kind.", "enum:plane|box|sphere|cylinder")],
        "plane": [
            ("point", None, "m", "", "A point of the plane.", _VEC),
            ("normal", None, "m", "", "Plane normal (not zero).", _VEC),
        ],
        "box": [
            ("min", None, "m", "", "Lower corner of the axis-aligned box.", _VEC),
            ("max", None, "m", "", "Upper corner; max > min componentwise.", _VEC),
        ],
        "sphere": [
            ("center", None, "m", "", "Centre.", _VEC),
            ("radius", None, "m", _LENGTH, "Radius.", "float"),
        ],
        "cylinder": [
            ("a", None, "m", "", "One end of the axis.", _VEC),
            ("b", None, "m", "", "The other end (not a).", _VEC),
            ("radius", None, "m", _LENGTH, "Radius.", "float"),
        ],
    },
}

#: Keys whose effect shows only in some scenes: ``{dotted key: (when, overrides)}``. ``when`` says in
#: words when the key acts (docs/scene.md prints it with the key); ``overrides`` are dotted keys (or
#: ``skeleton.node.<i>.<key>``, a node's key) that make the small bake of tests/test_keys.py such a
#: scene, where the test checks that moving the key changes the bake.
_DRYING = ("while the wood dries below mechanics.M_0", {"mechanics.M_0": 0.6})
_BREAKS = ("when connections break", {"mechanics.M_0": 0.6})
#: a drying log clamped at its root with no ground, under ten times its weight: its rods bend,
#: twist, shear and stretch
_LOADED = {"skeleton.node.0.anchored": True, "mechanics.gravity": [0.0, 0.0, -100.0], "mechanics.M_0": 0.6,
           "mechanics.ground": False}
_NEAR = "where a load bends, twists, shears or stretches the rods near that limit"
_DECAYED = {"wood.H_c_init": 0.2, "wood.H_l_init": 0.2}
_SETTLING = ("while pieces settle for longer than sleep_time seconds of mechanics",
             {"time.schedule": "fixed", "mechanics.N_mech": 2000, "mechanics.ground_height": -0.3})
CONDITIONAL: dict[str, tuple[str, dict[str, Any]]] = {
    "weakpoints.junction_boost": ("near a fork of the skeleton", {}),
    "weakpoints.junction_radius": ("near a fork of the skeleton", {}),
    "fungi.M_min": ("where the wood is drier than the window's lower end", {"moisture.M_init": 0.3}),
    "mechanics.S": _DRYING, "mechanics.s": _DRYING, "mechanics.S_R": _DRYING, "mechanics.S_T": _DRYING,
    "bark.drying": _DRYING,
    "time.strain_tolerance": ("while the wood dries below mechanics.M_0 and nothing else calls a solve",
                              {"mechanics.M_0": 0.6, "time.tolerance": 1.0}),
    "mechanics.L_0_stretch": _BREAKS, "mechanics.L_0_shear": _BREAKS, "mechanics.L_0_bundle": _BREAKS,
    "mechanics.L_knee": _BREAKS, "mechanics.p_l_bundle": _BREAKS,
    "mechanics.L_0_bend": (_NEAR, _LOADED), "mechanics.L_0_twist": (_NEAR, _LOADED),
    "mechanics.p_l_stretch": (_NEAR, _LOADED),
    "mechanics.p_l_shear": (_NEAR, {**_LOADED, "mechanics.L_0_shear": 0.002}),
    "mechanics.p_l_bend": (_NEAR, {**_LOADED, "mechanics.L_0_bend": 0.002}),
    "mechanics.p_l_twist": (_NEAR, {**_LOADED, "mechanics.L_0_twist": 0.0002}),
    "mechanics.I_fail": ("where decay brings a connection's integrity near it",
                         {"wood.H_c_init": 0.6, "wood.H_l_init": 0.6}),
    "mechanics.m_crumble": ("where decay brings an element's remaining mass near it", _DECAYED),
    "mechanics.N_mech": ("with time.schedule = 'fixed' (the adaptive schedule runs to rest)",
                         {"time.schedule": "fixed"}),
    "mechanics.residual_tolerance": ("with mechanics.solver = 'implicit'", {"mechanics.solver": "implicit"}),
    "mechanics.connection_shear": ("with mechanics.solver = 'implicit' where connections strain",
                                   {"mechanics.solver": "implicit", "mechanics.M_0": 0.6}),
    "wood.species": ("with mechanics.solver = 'implicit'", {"mechanics.solver": "implicit"}),
    "mechanics.sleep_speed": _SETTLING, "mechanics.sleep_time": _SETTLING,
    "time.max_mechanics": ("while a piece moves for longer than that in one macro step (a fall)",
                           {"mechanics.ground_height": -1.0}),
    "mechanics.clamp_depth": ("with an anchored root", {"skeleton.node.0.anchored": True}),
    "bark.shedding": ("where the wood under the bark has decayed or its moisture cycles", _DECAYED),
}

#: Sections whose parameters may be overridden per tissue (``[tissue.<name>]``).
TISSUE_SECTIONS: tuple[str, ...] = ("fungi", "moisture", "mechanics", "transport", "wood")


@dataclass(frozen=True)
class TissueDefault:
    """A tissue's own default of a parameter: ``value`` times the section's value when
    ``relative`` (so a scene that scales a rate scales it in every tissue), else ``value``
    itself. A ``[tissue.<name>]`` key replaces it."""

    value: float
    relative: bool
    why: str


#: Where the tissues differ by default (woodstock §6, Figs. 13-14): sapwood holds the
#: carbohydrates (starch and sugars of the living ray cells) that brown rot feeds on; heartwood
#: holds extractives that defend it and a lignin-rich wall that white rot, the heart rot of
#: standing trees, consumes (docs/decisions.md, "Tissue defaults").
TISSUE_DEFAULTS: dict[str, dict[str, TissueDefault]] = {
    "sapwood": {
        "alpha_b0": TissueDefault(2.0, True, "brown rot grows twice as fast in carbohydrate-rich sapwood"),
    },
    "heartwood": {
        "alpha_w0": TissueDefault(2.0, True, "white rot grows twice as fast in heartwood (heart rot)"),
        "C_init": TissueDefault(0.3, False, "extractives: defence efficacy C starts at 0.3"),
        "beta_b": TissueDefault(3.0, True, "extractives inhibit brown rot three times more strongly"),
    },
}


def _parse_range(text: str) -> tuple[float | None, float | None, bool, bool]:
    text = text.strip()
    if text in ("", "any"):
        return None, None, False, False
    lo_open = text[0] == "("
    hi_open = text[-1] == ")"
    assert text[0] in "([" and text[-1] in ")]", text
    lo_s, hi_s = (p.strip() for p in text[1:-1].split(","))
    lo = None if lo_s in ("-inf", "") else float(lo_s)
    hi = None if hi_s in ("inf", "") else float(hi_s)
    return lo, hi, lo_open, hi_open


def _param(section: str, row: tuple) -> Param:
    """One :class:`Param` from a schema row."""
    name, default, unit, rng, doc = row[:5]
    kind = row[5] if len(row) > 5 else None
    choices: tuple[str, ...] = ()
    if kind is None:
        if isinstance(default, bool):
            kind = "bool"
        elif isinstance(default, int):
            kind = "int"
        elif isinstance(default, float):
            kind = "float"
        elif isinstance(default, str):
            kind = "str"
        else:  # pragma: no cover - schema bug
            raise AssertionError(f"cannot infer the kind of {section}.{name}")
    elif kind.startswith("enum:"):
        choices = tuple(kind[5:].split("|"))
        kind = "enum"
    lo, hi, lo_open, hi_open = _parse_range(rng)
    if kind == "vec3" and default is not None:
        default = tuple(float(x) for x in default)
    elif kind in ("list", "seasons") and default is not None:
        default = tuple(default)
    return Param(section, name, default, unit, lo, hi, lo_open, hi_open, kind, doc, choices)


def _params(section: str, rows: list[tuple]) -> dict[str, Param]:
    """``{name: Param}`` of a list of rows, in order."""
    table: dict[str, Param] = {}
    for row in rows:
        assert row[0] not in table, f"duplicate key {section}.{row[0]}"
        table[row[0]] = _param(section, row)
    return table


def _table(name: str, rows: dict[str, list[tuple]]) -> Table:
    keys = _params(name, rows[""])
    kinds = {kind: _params(name, kind_rows) for kind, kind_rows in rows.items() if kind}
    if kinds:
        assert keys["kind"].choices == tuple(kinds), f"{name}.kind choices differ from its kinds"
    for kind_keys in kinds.values():
        assert not set(kind_keys) & set(keys), f"{name}: a kind repeats a common key"
    return Table(name, keys, kinds)


#: ``{section: {name: Param}}`` of the scalar sections, in schema order.
PARAMS: dict[str, dict[str, Param]] = {sec: _params(sec, rows) for sec, rows in _SCHEMA.items()}
#: Section names of the scalar parameter tables (not ``skeleton``/``tissue``/the entry tables).
SECTIONS: tuple[str, ...] = tuple(PARAMS)
#: ``{name: Table}`` of the entry tables.
TABLES: dict[str, Table] = {name: _table(name, rows) for name, rows in _TABLE_SCHEMA.items()}
#: Entry tables written as arrays of tables at the top of a scene (``[[inoculation]]``).
ARRAY_TABLES: tuple[str, ...] = ("inoculation", "load", "collider")
#: Every top-level key of a scene (``[skeleton]`` is read by :mod:`wooddecay.strands.skeleton_loader`).
TOP_LEVEL: tuple[str, ...] = SECTIONS + ("skeleton", "tissue") + ARRAY_TABLES

#: Bare name -> Param for every tissue-overridable parameter.
TISSUE_KEYS: dict[str, Param] = {}
for _sec in TISSUE_SECTIONS:
    for _name, _p in PARAMS[_sec].items():
        assert _name not in TISSUE_KEYS, (
            f"parameter name {_name!r} appears in both [{TISSUE_KEYS[_name].section}] and [{_sec}]; "
            "tissue-overridable names must be unique"
        )
        TISSUE_KEYS[_name] = _p
del _sec, _name, _p


def get_param(key: str) -> Param:
    """The :class:`Param` of a dotted key ``section.name`` (``KeyError`` if there is none)."""
    section, _, name = key.partition(".")
    try:
        return PARAMS[section][name]
    except KeyError:
        raise KeyError(key) from None


# ---------------------------------------------------------------------------------------------
# In words (messages are one line)
# ---------------------------------------------------------------------------------------------
def _num(x: float) -> str:
    """Compact number for ranges: 1, 0.5, 1e-5, 1e13."""
    if x == int(x) and abs(x) <= 1e6:
        return str(int(x))
    text = f"{x:g}"
    if "e" in text:
        mant, exp = text.split("e")
        text = f"{mant}e{int(exp)}"
    return text


def format_range(p: Param) -> str:
    """Allowed values of ``p`` in words with the unit: ``(0, 1] m``, ``one of 'draft', 'final'``."""
    unit = f" {p.unit}" if p.unit else ""
    if p.kind == "enum":
        return "one of " + ", ".join(repr(c) for c in p.choices)
    if p.kind == "bool":
        return "true or false"
    if p.kind == "str":
        return "a string"
    if p.kind == "vec3":
        return f"a list of 3 finite numbers [x, y, z]{unit}"
    if p.kind == "list":
        return "a list of [day, M_1, M_2] rows (days >= 0 strictly increasing, M_2 < M_1) in day, kg/kg"
    if p.kind == "seasons":
        return "a list of [day_of_year, w_in, w_out, w_ground] rows (days in [0, 365.25) strictly increasing, factors in [0, 100])"
    if p.kind == "interval":
        return "[start, end] in days with 0 <= start < end"
    if p.kind == "region":
        return "a region table {kind = ..., ...}"
    if p.kind == "node_id":
        return "a skeleton node id (string or integer)"
    if p.lo is None and p.hi is None:
        what = "any integer" if p.kind == "int" else "any finite number"
        return what + unit
    lo = "(-inf" if p.lo is None else ("(" if p.lo_open else "[") + _num(p.lo)
    hi = "inf)" if p.hi is None else _num(p.hi) + (")" if p.hi_open else "]")
    return f"{lo}, {hi}{unit}"


def _derived_default(p: Param) -> str:
    """Words for a scalar key whose default is derived (``default`` None)."""
    if p.key == "scene.name":
        return "the file stem"
    if p.key == "strands.connect_radius":
        return f"{_num(CONNECT_FACTOR)} * r_s"
    if p.section == "bark" and p.name in next(iter(BARK_SPECIES.values())):
        return "from `species`"
    raise AssertionError(f"no words for the derived default of {p.key}")  # pragma: no cover - schema bug


def default_text(p: Param, required: bool = False) -> str:
    """The default of ``p`` as the page shows it; ``required``: a ``None`` default means the key
    must be given (entry tables)."""
    if p.default is None:
        return "required" if required else _derived_default(p)
    if p.kind == "vec3":
        return "[" + ", ".join(_num(c) for c in p.default) + "]"
    if p.kind in ("list", "seasons"):
        return "[]"
    if isinstance(p.default, str):
        return f'"{p.default}"'
    return format_value(p.default, limit=200)


def describe() -> str:
    """The scalar sections as a Markdown table each (for docs and ``wooddecay inspect``)."""
    lines: list[str] = []
    for section, table in PARAMS.items():
        lines.append(f"### [{section}]")
        lines.append("")
        lines.append("| key | default | allowed | meaning |")
        lines.append("|---|---|---|---|")
        for p in table.values():
            lines.append(f"| `{p.name}` | {default_text(p)} | {format_range(p)} | {p.doc} |")
        lines.append("")
    lines += ["### Tissue defaults", "", "| tissue | key | default | why |", "|---|---|---|---|"]
    for tissue, table in TISSUE_DEFAULTS.items():
        for name, d in table.items():
            lines.append(f"| {tissue} | `{name}` | {'x ' if d.relative else ''}{_num(d.value)} | {d.why} |")
    lines.append("")
    return "\n".join(lines)
