"""Wood species: their orthotropic elastic constants, shrinkage, strength and density, with
sources, and the rod stiffnesses that give the converged bundle those constants (docs/model.md §4
"Species moduli"; ``[wood] species``).

:data:`SPECIES` holds clear wood at 12% moisture content. Sources:

* WH: Forest Products Laboratory, *Wood Handbook: Wood as an Engineering Material*, General
  Technical Report FPL-GTR-282, USDA Forest Service, 2021. Table 5-1 (elastic ratios E_T/E_L,
  E_R/E_L, G_LR/E_L, G_LT/E_L, G_RT/E_L), Table 5-3a (modulus of elasticity in bending, modulus of
  rupture, compression parallel to grain, tension perpendicular to grain, specific gravity at 12%),
  Table 4-3 (shrinkage from green to oven-dry, radial and tangential; longitudinal 0.1-0.2% for
  normal wood, §4, taken as 0.15%).
* JWS: Table 1 of "A finite element model of semi-rigid mortise-and-tenon joint considering glue
  line and friction coefficient", Journal of Wood Science (2019), doi:10.1186/s10086-019-1794-4:
  the nine elastic constants of beech wood.

E_L is WH's bending modulus, which includes some shear deflection (WH §5: E_L is about 10% above
it); the table keeps the printed figure. The density is rho_dry = 1000 kg/m^3 times the specific
gravity at 12% (oven-dry mass over volume at 12%), the mass the rods carry per unit volume of dry
wood (docs/model.md §2).

:class:`RodModuli` are the eight stiffness parameters the bundle is built from (strand E and G,
the REG connection's central moduli by the R, T and L components of its rest direction and its
co-rotated offset's moduli along the pair's R, T and L axes;
:func:`wooddecay.sim.mechanics.base_stiffness`). Each species' ``rods`` are the output of
``python benchmarks/moduli.py --calibrate`` (:func:`wooddecay.studies.moduli.calibrate`), as
fractions of E_L, so that the converged bundle's homogenised moduli match the table; the same
script checks them (docs/decisions.md, "Species moduli").
"""
from __future__ import annotations

from typing import NamedTuple

#: the homogenised moduli a species gives, in the order of :class:`Species`
MODULI = ("E_L", "E_R", "E_T", "G_LR", "G_LT", "G_RT")


class RodModuli(NamedTuple):
    """Stiffness parameters of the rods (Pa): the strand's E and G (stretch and bend E A, E I;
    shear and twist G A, G J), the REG connection's central modulus by the R, T and L components
    of its rest direction n (2 r_s l / |dp_0| (a_R n_r^2 + a_T n_t^2 + a_L n_l^2)) and the moduli of
    its co-rotated offset along the pair's R, T and L axes (2 r_s l / |dp_0| (b_R, b_T, b_L),
    :func:`wooddecay.sim.equilibrium.offset_tensor`)."""

    E: float
    G: float
    a_R: float
    a_T: float
    a_L: float
    b_R: float
    b_T: float
    b_L: float

    def scaled(self, factor: float) -> RodModuli:
        return RodModuli(*(factor * v for v in self))


class Species(NamedTuple):
    """Clear wood at 12% moisture (module docstring): moduli in Pa, shrinkage as fractions from
    green to oven-dry, strengths in Pa, density in kg/m^3, and the calibrated rods as fractions
    of E_L."""

    name: str
    botanical: str
    E_L: float
    E_R: float
    E_T: float
    G_LR: float
    G_LT: float
    G_RT: float
    shrink_L: float
    shrink_R: float
    shrink_T: float
    bending_strength: float  # modulus of rupture
    compression_parallel: float
    tension_perpendicular: float
    rho_dry: float
    source: str
    rods: RodModuli  # calibrated, per unit E_L

    def moduli(self) -> dict[str, float]:
        """The six homogenised moduli (:data:`MODULI`), Pa."""
        return {k: getattr(self, k) for k in MODULI}

    def rod_moduli(self) -> RodModuli:
        """The rods' :class:`RodModuli` in Pa."""
        return self.rods.scaled(self.E_L)


def _ratios(E_L: float, T: float, R: float, LR: float, LT: float, RT: float) -> dict[str, float]:
    """WH Table 5-1's ratios (E_T, E_R, G_LR, G_LT, G_RT over E_L) as moduli."""
    return {"E_L": E_L, "E_R": R * E_L, "E_T": T * E_L, "G_LR": LR * E_L, "G_LT": LT * E_L, "G_RT": RT * E_L}


#: the species a scene may name (``[wood] species``)
SPECIES: dict[str, Species] = {
    "oak": Species(
        "oak", "Quercus rubra (northern red oak)", **_ratios(12.5e9, 0.082, 0.154, 0.089, 0.081, 0.020),
        shrink_L=0.0015, shrink_R=0.040, shrink_T=0.086, bending_strength=99e6, compression_parallel=46.6e6,
        tension_perpendicular=5.5e6, rho_dry=630.0,
        source="WH Tables 5-1, 5-3a, 4-3; Table 5-1 gives no G_RT for the oaks: 0.020 E_L, the mean of its "
               "hardwoods that have one",
        rods=RodModuli(0.5527, 0.04698, 0.02274, 0.01880, 0.0, 0.07832, 0.03976, 0.04532)),
    "beech": Species(
        "beech", "Fagus (beech)", E_L=12.205e9, E_R=1.858e9, E_T=0.774e9, G_LR=0.899e9, G_LT=0.595e9,
        G_RT=0.195e9, shrink_L=0.0015, shrink_R=0.055, shrink_T=0.119, bending_strength=103e6,
        compression_parallel=50.3e6, tension_perpendicular=7.0e6, rho_dry=640.0,
        source="moduli JWS Table 1; shrinkage, strength and density of American beech, WH Tables 4-3, 5-3a",
        rods=RodModuli(0.8122, 0.04971, 0.1887, 0.004336, 0.0, 0.05147, 0.02755, 0.01956)),
    "pine": Species(
        "pine", "Pinus taeda (loblolly pine)", **_ratios(12.3e9, 0.078, 0.113, 0.082, 0.081, 0.013),
        shrink_L=0.0015, shrink_R=0.048, shrink_T=0.074, bending_strength=88e6, compression_parallel=49.2e6,
        tension_perpendicular=3.2e6, rho_dry=510.0, source="WH Tables 5-1, 5-3a, 4-3",
        rods=RodModuli(0.5759, 0.04694, 0.01148, 0.05034, 0.0, 0.05642, 0.03210, 0.04264)),
    "spruce": Species(
        "spruce", "Picea sitchensis (Sitka spruce)", **_ratios(10.8e9, 0.043, 0.078, 0.064, 0.061, 0.003),
        shrink_L=0.0015, shrink_R=0.043, shrink_T=0.075, bending_strength=70e6, compression_parallel=38.7e6,
        tension_perpendicular=2.6e6, rho_dry=400.0, source="WH Tables 5-1, 5-3a, 4-3",
        rods=RodModuli(0.7190, 0.04494, 0.008780, 0.07790, 0.0, 0.03764, 0.01018, 0.03248)),
    "birch": Species(
        "birch", "Betula alleghaniensis (yellow birch)", **_ratios(13.9e9, 0.050, 0.078, 0.074, 0.068, 0.017),
        shrink_L=0.0015, shrink_R=0.073, shrink_T=0.095, bending_strength=114e6, compression_parallel=56.3e6,
        tension_perpendicular=6.3e6, rho_dry=620.0, source="WH Tables 5-1, 5-3a, 4-3",
        rods=RodModuli(0.6294, 0.04469, 0.01815, 0.02552, 0.0, 0.03687, 0.02120, 0.04006)),
}
