"""wooddecay: fungal wood decay (Woodstock, SIGGRAPH 2026) baked into USD and glTF assets.

Python API (docs/architecture.md "Python API")::

    import wooddecay as wd
    scene = wd.load_scene("samples/log.toml", overrides={"time.days": 30})
    model = wd.build_model(scene)
    mesh = wd.build_meshlets(model)
"""
from .errors import InputError
from .export.compare import compare_usd
from .export.gltf import export_gltf
from .export.usd import export_usd
from .meshlets.sweep import Meshlets, build_meshlets
from .model import WoodModel, build_model
from .scene import Scene, load_scene, parse_scene
from .sim.driver import Simulation

__all__ = ["InputError", "Meshlets", "compare_usd", "export_gltf", "export_usd", "Scene", "WoodModel", "build_meshlets", "build_model", "load_scene",
           "parse_scene", "Simulation"]
from .version import __version__ as __version__
