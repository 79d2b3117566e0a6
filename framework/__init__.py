"""crashlab: vehicle collision models compared, and accidents reconstructed by multi-objective search."""
from .errors import InputError
from .model import CollisionModel
from .outcome import Outcome
from .population import Population, Variants
from .registry import available_models, available_optimizers, get_model, get_optimizer
from .scene import Scene
from .scene_file import load_scene

__all__ = ["InputError", "Outcome", "Population", "Variants", "Scene", "CollisionModel", "load_scene", "simulate",
           "available_models", "available_optimizers", "get_model", "get_optimizer"]


def simulate(scene, model: str = "impulse", **options) -> Outcome:
    """Simulate a Scene (or a scene file path) with a registered model; options go to the model."""
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    return get_model(model, **options).simulate(scene)

