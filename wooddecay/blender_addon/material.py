"""Blender side of the Wood Decay material: the node group of :mod:`.shader` as Blender nodes,
and the material that feeds it from the mesh attributes (docs/architecture.md "Blender add-on").

* :func:`ensure_group` builds (or reuses) the "Wood Decay" ShaderNodeTree node group;
* :func:`build_material` makes a material: one Attribute node per attribute present on the
  meshes, the crack map's nodes when the bake has one (:func:`crack_map_nodes`), the "Wood
  Decay" group node (all the controls), Material Output.
"""
from __future__ import annotations

import bpy

from .shader import COLOR, DATA, FLOAT, GROUP_NAME, INPUTS, MATERIAL_NAME, OUTPUTS, SHADER, VECTOR, In, Out
from .shader import wood_decay_graph

SOCKET_TYPES = {FLOAT: "NodeSocketFloat", COLOR: "NodeSocketColor", VECTOR: "NodeSocketVector",
                SHADER: "NodeSocketShader"}
#: Attribute node output used for each kind of data input
ATTRIBUTE_OUTPUT = {FLOAT: "Fac", VECTOR: "Vector", COLOR: "Color"}
#: marks node groups made by this add-on (custom property) and the graph version
GROUP_TAG = "wooddecay_group"
GROUP_VERSION = 2  # 2: bark cracks (an older group is rebuilt, see group_ok)
#: the UV map of the bake's crack map (wooddecay.export.bark_texture)
CRACK_UV = "barkUV"
#: UDIM number of the crack map's tile of frame 0
UDIM_FIRST = 1001
#: strength of the procedural furrows where the crack map draws the simulated cracks
CRACK_MAP_FURROWS = 0.25


def _rgba(v):
    """An RGB colour with an alpha of 1 (RGBA unchanged)."""
    return v if len(v) == 4 else (*v, 1.0)


def find_socket(sockets, key):
    """Socket by index, identifier or (enabled first) name."""
    if isinstance(key, int):
        return sockets[key]
    for s in sockets:
        if s.identifier == key:
            return s
    named = [s for s in sockets if s.name == key]
    enabled = [s for s in named if getattr(s, "enabled", True)]
    if not (enabled or named):
        raise KeyError(f"no socket {key!r} among {[s.identifier for s in sockets]}")
    return (enabled or named)[0]


def _interface_socket(tree, spec, in_out: str):
    sock = tree.interface.new_socket(spec.name, in_out=in_out, socket_type=SOCKET_TYPES[spec.kind])
    if spec.description:
        sock.description = spec.description
    if spec.kind != SHADER and in_out == "INPUT":
        sock.default_value = _rgba(spec.default) if spec.kind == COLOR else spec.default
        if spec.min is not None:
            sock.min_value = spec.min
        if spec.max is not None:
            sock.max_value = spec.max
        if spec.kind == VECTOR and spec.attribute:
            sock.hide_value = True
    return sock


def _layout(graph, created, gin, gout) -> None:
    """Columns by depth (longest path from the group input), rows in creation order."""
    depth = []
    for node in graph.nodes:
        d = 1 + max((depth[v.node] for v in node.refs() if isinstance(v, Out)), default=0)
        depth.append(d)
    rows: dict[int, int] = {}
    for n, d in zip(created, depth):
        rows[d] = rows.get(d, 0) + 1
        n.location = (d * 220.0, -rows[d] * 190.0)
    gin.location = (-80.0, 0.0)
    gout.location = ((max(depth, default=0) + 1) * 220.0, 0.0)


def group_ok(tree) -> bool:
    """True when ``tree`` is a Wood Decay group of this version with every input and output."""
    if tree is None or tree.get(GROUP_TAG) != GROUP_VERSION:
        return False
    items = {(i.in_out, i.name) for i in tree.interface.items_tree if getattr(i, "item_type", "") == "SOCKET"}
    return (all(("INPUT", s.name) in items for s in INPUTS)
            and all(("OUTPUT", s.name) in items for s in OUTPUTS))


def build_group():
    """A new "Wood Decay" node group (Blender may suffix the name when one exists)."""
    graph = wood_decay_graph()
    tree = bpy.data.node_groups.new(GROUP_NAME, "ShaderNodeTree")
    tree[GROUP_TAG] = GROUP_VERSION
    tree.description = ("Fungal decay of wood driven by the wooddecay attributes H_c, H_l, M, wood, ring, faceKind, "
                        "bark_crack, bark_crack_depth")
    for spec in OUTPUTS:
        _interface_socket(tree, spec, "OUTPUT")
    for spec in INPUTS:
        _interface_socket(tree, spec, "INPUT")
    nodes, links = tree.nodes, tree.links
    gin, gout = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    created = []
    for node in graph.nodes:
        n = nodes.new(node.idname)
        for k, v in node.props.items():
            setattr(n, k, v)
        if node.label:
            n.label = node.label
        created.append(n)

    def connect(value, socket):
        if isinstance(value, Out):
            links.new(find_socket(created[value.node].outputs, value.key), socket)
        elif isinstance(value, In):
            links.new(gin.outputs[value.name], socket)
        else:
            socket.default_value = _rgba(value) if socket.type == "RGBA" else value

    for node, n in zip(graph.nodes, created):
        for key, value in node.inputs.items():
            connect(value, find_socket(n.inputs, key))
    for name, value in graph.outputs.items():
        connect(value, gout.inputs[name])
    _layout(graph, created, gin, gout)
    return tree


def ensure_group():
    """The existing Wood Decay group of this version (keeps the user's edits), else a new one."""
    for tree in bpy.data.node_groups:
        if tree.bl_idname == "ShaderNodeTree" and tree.name.startswith(GROUP_NAME) and group_ok(tree):
            return tree
    return build_group()


def build_material(attributes, name: str = MATERIAL_NAME, crack_map: str | None = None):
    """A material whose "Wood Decay" group node reads the mesh attributes in ``attributes``
    (names); data inputs whose attribute is missing keep their defaults (sound, dry wood, no
    bark). With ``crack_map`` (the first tile of the bake's ``<stem>_bark.<UDIM>.png``) and the ``barkUV`` map, the
    group's Bark Crack input comes from it (:func:`crack_map_nodes`) instead of the coarser
    per-vertex ``bark_crack``."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    group = tree.nodes.new("ShaderNodeGroup")
    group.node_tree = ensure_group()
    group.name = group.label = GROUP_NAME
    group.width = 240.0
    group.location = (0.0, 0.0)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.location = (340.0, 0.0)
    tree.links.new(group.outputs["BSDF"], out.inputs["Surface"])
    attributes = set(attributes)
    row = 0
    for spec in DATA:
        if spec.attribute not in attributes:
            continue
        node = tree.nodes.new("ShaderNodeAttribute")
        node.attribute_type = "GEOMETRY"
        node.attribute_name = spec.attribute
        node.label = spec.attribute
        node.location = (-260.0, -row * 110.0)
        row += 1
        tree.links.new(node.outputs[ATTRIBUTE_OUTPUT[spec.kind]], group.inputs[spec.name])
    if crack_map is not None and CRACK_UV in attributes:
        tree.links.new(crack_map_nodes(tree, crack_map), group.inputs["Bark Crack"])
        group.inputs["Bark Furrows"].default_value = CRACK_MAP_FURROWS
    mat["wooddecay"] = True
    return mat


def crack_map_nodes(tree, path: str):
    """Nodes reading the crack map (wooddecay.export.bark_texture): ``path`` is its first UDIM tile
    (``<stem>_bark.1001.png``), frame k's map is tile 1001 + k. The V-profile is read at
    ``barkUV`` moved into the tile of the current frame (a Value node driven by ``frame``, held to
    the first and last tile): u' = fract(u) + k mod 10, v' = v + floor(k / 10). Returns the output
    socket."""
    img = bpy.data.images.load(path, check_existing=True)
    img.source = "TILED"  # finds the set's other tiles on disk
    img.colorspace_settings.name = "Non-Color"
    last = max(t.number for t in img.tiles) - UDIM_FIRST
    uv = tree.nodes.new("ShaderNodeUVMap")
    uv.uv_map = CRACK_UV
    uv.location = (-1300.0, 300.0)
    xyz = tree.nodes.new("ShaderNodeSeparateXYZ")
    xyz.location = (-1120.0, 300.0)
    tree.links.new(uv.outputs["UV"], xyz.inputs["Vector"])
    frame = tree.nodes.new("ShaderNodeValue")
    frame.label = "frame"
    frame.location = (-1300.0, 520.0)
    fc = frame.outputs[0].driver_add("default_value")
    fc.driver.expression = "frame"
    at = [-940.0]

    def math(op, a, b=None):
        m = tree.nodes.new("ShaderNodeMath")
        m.operation = op
        m.location = (at[0], 420.0)
        at[0] += 140.0
        for sock, v in zip(m.inputs, (a, b)):
            if isinstance(v, (int, float)):
                sock.default_value = v
            elif v is not None:
                tree.links.new(v, sock)
        return m.outputs[0]

    k = math("MINIMUM", math("MAXIMUM", math("ROUND", frame.outputs[0]), 0.0), float(last))
    move = tree.nodes.new("ShaderNodeCombineXYZ")
    move.location = (at[0], 300.0)
    tree.links.new(math("ADD", math("FRACT", xyz.outputs["X"]), math("MODULO", k, 10.0)), move.inputs["X"])
    tree.links.new(math("ADD", xyz.outputs["Y"], math("FLOOR", math("DIVIDE", k, 10.0))), move.inputs["Y"])
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation, tex.extension = img, "Linear", "EXTEND"
    tex.location = (at[0] + 180.0, 300.0)
    tree.links.new(move.outputs["Vector"], tex.inputs["Vector"])
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    sep.location = (at[0] + 460.0, 300.0)
    tree.links.new(tex.outputs["Color"], sep.inputs["Color"])
    return sep.outputs["Red"]


def group_node(mat):
    """The Wood Decay group node of ``mat`` (None when it has none)."""
    if mat is None or not mat.use_nodes:
        return None
    for n in mat.node_tree.nodes:
        if n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None and n.node_tree.name.startswith(GROUP_NAME):
            return n
    return None
