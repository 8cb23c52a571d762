"""The Wood Decay material as data, with no ``bpy`` (docs/architecture.md "Blender add-on"; woodstock §8.3,
offline rendering: a PBR material with procedural textures in wood-local coordinates, albedo and
roughness modulated by coherent noise, the same noise as small-scale relief, colour and roughness
blended as functions of H_c, H_l and M).

:func:`wood_decay_graph` describes the "Wood Decay" shader node group: which Blender nodes, their
settings and links, and the group's inputs (:data:`DATA` from the mesh attributes,
:data:`CONTROLS` for the artist) and outputs (:data:`OUTPUTS`). :mod:`.material` turns the
description into Blender nodes; keeping it here lets it be read and checked without Blender.

What the group does, per shading point, from the attributes of a wooddecay bake (the USD
primvars; glTF attributes are renamed to them on import, see :mod:`.importer`):

* wood: ``wood`` = (r, phi, s) rest wood-local coordinates (metres, radians, metres) become a
  rest position P = (r cos phi, r sin phi, s), so every texture sticks to the wood as it bends
  and breaks. Growth rings from ``ring`` (ring age, years): the fraction of the year turns from
  earlywood (Base Color) to latewood (Latewood Color) over the last "Latewood Fraction" of each
  ring, the ring boundaries wobbled by coherent noise of P ("Ring Distortion"). Grain: noise of
  P stretched along the fibres (s / "Grain Stretch") streaks the colour; a larger-scale coherent
  noise ("Noise Scale", "Noise Strength") varies colour and roughness from place to place and
  mottles the rot fronts ("Rot Mottling").
* brown rot (cellulose gone while lignin stays, b = (1 - H_c) H_l x strength): towards a dark
  reddish brown, rough, with cubical checking (dark cracks on a Voronoi pattern, longer along the
  grain) where it is advanced.
* white rot (lignin gone, w = (1 - H_l) x strength): bleached towards a pale straw colour, with
  fibrous streaks along the grain and dark zone lines where the white-rot front stands.
* moisture ``M`` (kg/kg): from "Moisture Dry" to "Moisture Wet" the wood darkens (up to
  "Moisture Darkening") and turns glossier ("Moisture Gloss" lowers the roughness).
* bark (``faceKind`` == 0): furrowed bark colour and roughness ("Bark Furrows" scales the
  procedural furrows; the material lowers it where the bake's crack map draws the simulated
  cracks); decay shows through it by "Bark Decay". Where there is no face kind (an unlinked
  input) every face is wood.
* bark cracks (woodification §5: a crack is widest in its middle, V-shaped in depth, its floor
  dark): ``bark_crack`` is 1 on a crack's centre line and falls linearly to 0 just past its edge,
  ``bark_crack_depth`` the crack's depth there (metres). The crack floor starts where
  ``bark_crack`` passes 1 - "Crack Width" (a smoothstep over a short band, so the crack's edge is
  crisp even where a triangle spans it); there the bark turns towards "Crack Color", darkest on
  the centre line, and towards "Crack Roughness", and the relief sinks by ``bark_crack`` plus the
  depth (a groove, V-shaped like the crack). Only bark faces crack; with both attributes 0 or
  missing (older bakes: the inputs' defaults are 0) the bark is exactly as without cracks.

Outputs: the BSDF (Principled) and, for compositing or AOVs, the colour, roughness and the decay
factor max(b, w).
"""
from __future__ import annotations

from dataclasses import dataclass, field

GROUP_NAME = "Wood Decay"
MATERIAL_NAME = "Wood Decay"

FLOAT, COLOR, VECTOR, SHADER = "FLOAT", "COLOR", "VECTOR", "SHADER"


@dataclass(frozen=True)
class Socket:
    """One input or output of the node group."""

    name: str
    kind: str  # FLOAT, COLOR, VECTOR or SHADER
    default: float | tuple = 0.0
    min: float | None = None
    max: float | None = None
    description: str = ""
    attribute: str = ""  # mesh attribute that drives it (DATA only)


#: inputs fed from the mesh attributes by Attribute nodes in the material; an input left
#: unlinked (attribute missing) keeps its default: sound, dry wood, no bark
DATA = (
    Socket("H_c", FLOAT, 1.0, 0.0, 1.0, "Cellulose health (1 sound, 0 gone): attribute H_c", "H_c"),
    Socket("H_l", FLOAT, 1.0, 0.0, 1.0, "Lignin health (1 sound, 0 gone): attribute H_l", "H_l"),
    Socket("M", FLOAT, 0.2, 0.0, 10.0, "Moisture content (kg/kg): attribute M", "M"),
    Socket("Wood", VECTOR, (0.0, 0.0, 0.0), None, None,
           "Rest wood-local coordinates (r, phi, s): attribute wood", "wood"),
    Socket("Ring", FLOAT, 0.0, 0.0, 10000.0, "Ring age (years): attribute ring", "ring"),
    Socket("Face Kind", FLOAT, 1.0, 0.0, 2.0, "0 bark, 1 side, 2 cap: attribute faceKind", "faceKind"),
    Socket("Bark Crack", FLOAT, 0.0, 0.0, 1.0,
           "1 on a bark crack's centre line, 0 past its edge: attribute bark_crack", "bark_crack"),
    Socket("Crack Depth", FLOAT, 0.0, 0.0, 0.1,
           "Depth of the bark crack (m), V-shaped across it: attribute bark_crack_depth", "bark_crack_depth"),
)

#: the artist's controls
CONTROLS = (
    Socket("Base Color", COLOR, (0.62, 0.42, 0.22), description="Sound earlywood colour"),
    Socket("Latewood Color", COLOR, (0.40, 0.23, 0.10), description="Sound latewood colour"),
    Socket("Ring Contrast", FLOAT, 0.6, 0.0, 1.0, "How much of the latewood colour the rings show"),
    Socket("Latewood Fraction", FLOAT, 0.35, 0.01, 1.0, "Part of each ring that turns to latewood"),
    Socket("Ring Distortion", FLOAT, 0.4, 0.0, 5.0, "Wobble of the ring boundaries (rings)"),
    Socket("Grain Scale", FLOAT, 90.0, 0.0, 10000.0, "Scale of the grain streaks (1/m)"),
    Socket("Grain Stretch", FLOAT, 12.0, 1.0, 1000.0, "Streak length along the fibres over their width"),
    Socket("Grain Strength", FLOAT, 0.25, 0.0, 1.0, "Brightness variation of the grain"),
    Socket("Noise Scale", FLOAT, 12.0, 0.0, 10000.0, "Scale of the coherent colour noise (1/m)"),
    Socket("Noise Strength", FLOAT, 0.15, 0.0, 1.0, "Brightness variation of the coherent noise"),
    Socket("Rot Mottling", FLOAT, 0.5, 0.0, 1.0, "How much the coherent noise breaks up the decay fronts"),
    Socket("Brown Rot Color", COLOR, (0.10, 0.036, 0.014), description="Colour of advanced brown rot"),
    Socket("Brown Rot Strength", FLOAT, 1.5, 0.0, 10.0, "Brown rot colour per unit of cellulose lost"),
    Socket("Brown Rot Cracks", FLOAT, 0.7, 0.0, 1.0, "Darkness of the cubical checking of advanced brown rot"),
    Socket("Crack Scale", FLOAT, 80.0, 0.0, 10000.0, "Scale of the cubical checking (1/m)"),
    Socket("White Rot Color", COLOR, (0.60, 0.53, 0.38), description="Colour of bleached, white-rotted wood"),
    Socket("White Rot Strength", FLOAT, 1.5, 0.0, 10.0, "White rot colour per unit of lignin lost"),
    Socket("White Rot Fibres", FLOAT, 0.5, 0.0, 1.0, "Fibrous streaks in white-rotted wood"),
    Socket("Zone Lines", FLOAT, 0.6, 0.0, 1.0, "Dark zone lines along the white-rot front"),
    Socket("Moisture Darkening", FLOAT, 0.45, 0.0, 1.0, "Darkening of wet wood"),
    Socket("Moisture Gloss", FLOAT, 0.5, 0.0, 1.0, "Loss of roughness of wet wood"),
    Socket("Moisture Dry", FLOAT, 0.25, 0.0, 10.0, "Moisture (kg/kg) below which wood looks dry"),
    Socket("Moisture Wet", FLOAT, 1.0, 0.0, 10.0, "Moisture (kg/kg) at which wood looks soaked"),
    Socket("Roughness", FLOAT, 0.55, 0.0, 1.0, "Roughness of sound wood"),
    Socket("Rot Roughness", FLOAT, 0.95, 0.0, 1.0, "Roughness of rotted wood"),
    Socket("Bark Color", COLOR, (0.13, 0.095, 0.07), description="Bark colour"),
    Socket("Bark Scale", FLOAT, 60.0, 0.0, 10000.0, "Scale of the bark furrows (1/m)"),
    Socket("Bark Furrows", FLOAT, 1.0, 0.0, 1.0,
           "Strength of the procedural bark furrows (lowered where the bake's crack map draws the cracks)"),
    Socket("Bark Roughness", FLOAT, 0.9, 0.0, 1.0, "Roughness of bark"),
    Socket("Bark Decay", FLOAT, 0.6, 0.0, 1.0, "How much decay shows through the bark"),
    Socket("Crack Color", COLOR, (0.03, 0.017, 0.009), description="Colour of the floor of a bark crack"),
    Socket("Crack Width", FLOAT, 0.5, 0.0, 1.0,
           "Part of a bark crack's band (Bark Crack above 1 - width) that shows its dark floor"),
    Socket("Crack Roughness", FLOAT, 1.0, 0.0, 1.0, "Roughness of the floor of a bark crack"),
    Socket("Bump Strength", FLOAT, 0.3, 0.0, 1.0, "Strength of the grain, fibre, crack and bark relief"),
)

OUTPUTS = (
    Socket("BSDF", SHADER),
    Socket("Color", COLOR, (0.0, 0.0, 0.0)),
    Socket("Roughness", FLOAT, 0.0),
    Socket("Decay", FLOAT, 0.0, description="max(brown rot, white rot) factor"),
)

INPUTS = DATA + CONTROLS

#: near-black of the cracks and zone lines
BLACK = (0.012, 0.008, 0.005)
#: bump height per unit of the height signal (m)
BUMP_DISTANCE = 0.0015
#: band of Bark Crack over which a crack's floor fades in (smoothstep from 1 - Crack Width)
CRACK_EDGE = 0.15
#: darkness of a crack's floor at its edge relative to its centre line (darkest mid-crack)
CRACK_EDGE_DARKNESS = 0.5
#: deepest groove the crack depth cuts into the relief (height units, BUMP_DISTANCE each)
CRACK_GROOVE_MAX = 4.0


# --------------------------------------------------------------------------- graph description

@dataclass(frozen=True)
class In:
    """A group input (by name)."""

    name: str


@dataclass(frozen=True)
class Out:
    """Output ``key`` (identifier, name or index) of node ``node`` (an index into Graph.nodes)."""

    node: int
    key: str | int = 0


@dataclass
class Node:
    """A Blender node: ``idname`` (bl_idname), ``props`` set before its inputs, ``inputs``
    (key -> constant, :class:`In` or :class:`Out`; keys are socket identifiers, names or
    indices)."""

    idname: str
    props: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    label: str = ""

    def refs(self):
        return [v for v in self.inputs.values() if isinstance(v, (In, Out))]


class Graph:
    """A node graph under construction: helpers add a node and return its output."""

    def __init__(self):
        self.nodes: list[Node] = []
        self.outputs: dict = {}

    def add(self, idname: str, inputs: dict | None = None, label: str = "", **props) -> int:
        self.nodes.append(Node(idname, props, dict(inputs or {}), label))
        return len(self.nodes) - 1

    def math(self, op: str, a, b=None, clamp: bool = False, label: str = "") -> Out:
        inputs = {0: a} if b is None else {0: a, 1: b}
        return Out(self.add("ShaderNodeMath", inputs, label, operation=op, use_clamp=clamp))

    def mix(self, fac, a, b, label: str = "", blend: str = "MIX") -> Out:
        """Colour mix (ShaderNodeMix, RGBA), factor clamped."""
        node = self.add("ShaderNodeMix", {"Factor_Float": fac, "A_Color": a, "B_Color": b}, label,
                        data_type="RGBA", blend_type=blend, clamp_factor=True)
        return Out(node, "Result_Color")

    def mix_float(self, fac, a, b, label: str = "") -> Out:
        node = self.add("ShaderNodeMix", {"Factor_Float": fac, "A_Float": a, "B_Float": b}, label,
                        data_type="FLOAT", clamp_factor=True)
        return Out(node, "Result_Float")

    def map_range(self, value, from_min, from_max, to_min=0.0, to_max=1.0, interpolation="LINEAR",
                  label: str = "") -> Out:
        node = self.add("ShaderNodeMapRange", {"Value": value, "From Min": from_min, "From Max": from_max,
                                               "To Min": to_min, "To Max": to_max}, label,
                        data_type="FLOAT", interpolation_type=interpolation, clamp=True)
        return Out(node, "Result")

    def combine(self, x, y, z, label: str = "") -> Out:
        return Out(self.add("ShaderNodeCombineXYZ", {"X": x, "Y": y, "Z": z}, label), "Vector")

    def noise(self, vector, scale, detail: float = 2.0, roughness: float = 0.5, label: str = "") -> Out:
        node = self.add("ShaderNodeTexNoise", {"Vector": vector, "Scale": scale, "Detail": detail,
                                               "Roughness": roughness}, label, noise_dimensions="3D")
        return Out(node, "Fac")

    def value(self, color, value, label: str = "") -> Out:
        """``color`` with its HSV value multiplied by ``value``."""
        node = self.add("ShaderNodeHueSaturation", {"Color": color, "Value": value, "Fac": 1.0}, label)
        return Out(node, "Color")

    def centred(self, fac, strength, label: str = "") -> Out:
        """2 * strength * (fac - 0.5): a noise in [0, 1] as a signed variation."""
        return self.math("MULTIPLY", self.math("SUBTRACT", fac, 0.5), self.math("MULTIPLY", strength, 2.0),
                         label=label)

    def users(self) -> dict[str, int]:
        """How many node inputs read each group input."""
        count = {s.name: 0 for s in INPUTS}
        for node in self.nodes:
            for v in node.refs():
                if isinstance(v, In):
                    count[v.name] = count.get(v.name, 0) + 1
        for v in self.outputs.values():
            if isinstance(v, In):
                count[v.name] = count.get(v.name, 0) + 1
        return count


def wood_decay_graph() -> Graph:
    """The "Wood Decay" node group (module docstring)."""
    g = Graph()
    wood = g.add("ShaderNodeSeparateXYZ", {"Vector": In("Wood")}, "r, phi, s")
    r, phi, s = Out(wood, "X"), Out(wood, "Y"), Out(wood, "Z")
    x = g.math("MULTIPLY", r, g.math("COSINE", phi), label="x")
    y = g.math("MULTIPLY", r, g.math("SINE", phi), label="y")
    P = g.combine(x, y, s, label="rest position")
    fibre = g.combine(x, y, g.math("DIVIDE", s, In("Grain Stretch")), label="along the fibres")

    # coherent noise and grain
    big = g.noise(P, In("Noise Scale"), detail=3.0, label="coherent noise")
    grain = g.noise(fibre, In("Grain Scale"), detail=6.0, roughness=0.6, label="grain")

    # growth rings: earlywood -> latewood over the end of each year, boundaries wobbled
    ring = g.math("ADD", In("Ring"), g.centred(big, In("Ring Distortion")), label="ring coordinate")
    phase = g.math("FRACT", ring, label="year fraction")
    late = g.map_range(phase, g.math("SUBTRACT", 1.0, In("Latewood Fraction")), 1.0,
                       interpolation="SMOOTHSTEP", label="latewood")
    color = g.mix(g.math("MULTIPLY", late, In("Ring Contrast")), In("Base Color"), In("Latewood Color"),
                  label="rings")
    shade = g.math("ADD", g.math("ADD", 1.0, g.centred(grain, In("Grain Strength"))),
                   g.centred(big, In("Noise Strength")), label="grain and noise")
    color = g.value(color, shade, label="sound wood")

    # decay fronts broken up by the coherent noise
    mottle = g.math("ADD", 1.0, g.centred(big, In("Rot Mottling")), label="mottling")
    lost_c = g.math("SUBTRACT", 1.0, In("H_c"), clamp=True)
    lost_l = g.math("SUBTRACT", 1.0, In("H_l"), clamp=True)
    brown = g.math("MULTIPLY", g.math("MULTIPLY", g.math("MULTIPLY", lost_c, In("H_l")), In("Brown Rot Strength")),
                   mottle, clamp=True, label="brown rot")
    white = g.math("MULTIPLY", g.math("MULTIPLY", lost_l, In("White Rot Strength")), mottle, clamp=True,
                   label="white rot")

    # brown rot: dark reddish brown, cubical checking where advanced
    color = g.mix(brown, color, In("Brown Rot Color"), label="brown rot colour")
    cells = g.add("ShaderNodeTexVoronoi", {"Vector": g.combine(x, y, g.math("MULTIPLY", s, 0.5)),
                                           "Scale": In("Crack Scale")}, "cubical checking",
                  voronoi_dimensions="3D", feature="DISTANCE_TO_EDGE")
    edge = g.map_range(Out(cells, "Distance"), 0.0, 0.03, 1.0, 0.0, label="crack lines")
    advanced = g.map_range(g.math("MULTIPLY", lost_c, In("H_l")), 0.45, 0.85, interpolation="SMOOTHSTEP",
                           label="advanced brown rot")
    crack = g.math("MULTIPLY", g.math("MULTIPLY", edge, advanced), In("Brown Rot Cracks"), label="cracks")
    color = g.mix(crack, color, BLACK, label="cracks colour")

    # white rot: bleached, fibrous, zone lines at the front
    fibres = g.map_range(g.noise(fibre, g.math("MULTIPLY", In("Grain Scale"), 4.0), detail=4.0), 0.35, 0.65,
                         label="fibres")
    bleached = g.value(In("White Rot Color"),
                       g.math("SUBTRACT", 1.0, g.math("MULTIPLY", fibres, g.math("MULTIPLY", In("White Rot Fibres"), 0.5))),
                       label="fibrous white")
    color = g.mix(white, color, bleached, label="white rot colour")
    front = g.map_range(g.math("ABSOLUTE", g.math("SUBTRACT", white, 0.5)), 0.0, 0.04, 1.0, 0.0)
    zone = g.math("MULTIPLY", g.math("MULTIPLY", front, g.math("GREATER_THAN", white, 0.02)), In("Zone Lines"),
                  label="zone lines")
    color = g.mix(zone, color, BLACK, label="zone lines colour")
    decay = g.math("MAXIMUM", brown, white, label="decay")
    rough = g.mix_float(decay, In("Roughness"), In("Rot Roughness"))
    rough = g.math("MULTIPLY", rough, g.math("ADD", 1.0, g.centred(big, In("Noise Strength"))), clamp=True,
                   label="roughness")

    # bark: plates split by furrows along the grain, rough noise on the plates; decay shows
    # through by Bark Decay
    bark = g.math("LESS_THAN", In("Face Kind"), 0.5, label="is bark")
    bark_p = g.combine(x, y, g.math("DIVIDE", s, 3.0), label="bark coordinates")
    plates = g.add("ShaderNodeTexVoronoi", {"Vector": bark_p, "Scale": In("Bark Scale")}, "bark plates",
                   voronoi_dimensions="3D", feature="DISTANCE_TO_EDGE")
    furrow = g.map_range(Out(plates, "Distance"), 0.0, 0.12, label="plates")  # 0 in a furrow, 1 on a plate
    furrow = g.math("SUBTRACT", 1.0, g.math("MULTIPLY", In("Bark Furrows"), g.math("SUBTRACT", 1.0, furrow)),
                    label="furrow strength")
    scales = g.noise(bark_p, g.math("MULTIPLY", In("Bark Scale"), 5.0), detail=4.0, label="bark grit")
    bark_color = g.value(In("Bark Color"), g.math("ADD", g.math("MULTIPLY", furrow, 0.8),
                                                  g.math("MULTIPLY", scales, 0.6)), label="bark colour")
    bark_color = g.mix(g.math("MULTIPLY", brown, In("Bark Decay")), bark_color, In("Brown Rot Color"),
                       label="bark brown rot")
    bark_color = g.mix(g.math("MULTIPLY", white, g.math("MULTIPLY", In("Bark Decay"), 0.5)), bark_color,
                       In("White Rot Color"), label="bark white rot")
    # bark cracks: a dark, rough floor from 1 - Crack Width of Bark Crack on, darkest on the
    # centre line; everything scales with Bark Crack, so 0 (or no attribute) changes nothing
    crack_start = g.math("SUBTRACT", 1.0, In("Crack Width"), label="crack floor start")
    floor = g.map_range(In("Bark Crack"), crack_start, g.math("ADD", crack_start, CRACK_EDGE),
                        interpolation="SMOOTHSTEP", label="crack floor")
    centre = g.math("ADD", CRACK_EDGE_DARKNESS, g.math("MULTIPLY", In("Bark Crack"), 1.0 - CRACK_EDGE_DARKNESS))
    bark_color = g.mix(g.math("MULTIPLY", floor, centre), bark_color, In("Crack Color"), label="bark crack colour")
    bark_rough = g.mix_float(floor, In("Bark Roughness"), In("Crack Roughness"), label="bark crack roughness")

    color = g.mix(bark, color, bark_color, label="bark")
    rough = g.mix_float(bark, rough, bark_rough, label="bark roughness")

    # moisture: darker and glossier
    wet = g.map_range(In("M"), In("Moisture Dry"), In("Moisture Wet"), label="wetness")
    color = g.mix(g.math("MULTIPLY", wet, In("Moisture Darkening")), color, BLACK, label="wet colour")
    rough = g.math("MULTIPLY", rough, g.math("SUBTRACT", 1.0, g.math("MULTIPLY", wet, In("Moisture Gloss"))),
                   clamp=True, label="wet roughness")

    # relief: grain and fibres, cracks sunk, bark furrows and bark cracks
    height = g.math("ADD", g.math("MULTIPLY", grain, 0.3), g.math("MULTIPLY", fibres, white))
    height = g.math("SUBTRACT", height, crack)
    bark_height = g.math("ADD", furrow, g.math("MULTIPLY", scales, 0.3))
    depth = g.math("MINIMUM", g.math("DIVIDE", In("Crack Depth"), BUMP_DISTANCE), CRACK_GROOVE_MAX)
    groove = g.math("ADD", In("Bark Crack"), depth, label="crack groove")
    bark_height = g.math("SUBTRACT", bark_height, groove, label="bark relief")
    height = g.mix_float(bark, height, bark_height, label="height")
    bump = g.add("ShaderNodeBump", {"Strength": In("Bump Strength"), "Distance": BUMP_DISTANCE, "Height": height},
                 "relief")
    bsdf = g.add("ShaderNodeBsdfPrincipled", {"Base Color": color, "Roughness": rough, "Normal": Out(bump, "Normal")},
                 "wood")
    g.outputs = {"BSDF": Out(bsdf, "BSDF"), "Color": color, "Roughness": rough, "Decay": decay}
    return g
