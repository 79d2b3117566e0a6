"""The model instances evaluations use: one per process, model name and options, kept across generations (a
model may cache per-vehicle preparation: the multibody model settles each vehicle statically once). The cache
is this process's; clear it with `model_instance.cache_clear()` (a worker process starts empty)."""
import functools

from ..registry import get_model


@functools.lru_cache(maxsize=8)
def model_instance(name: str, options_items: tuple):
    """This process's instance of model `name` (a registered name or a 'module:Class' reference,
    crashlab.registry.get_model) with the options (sorted (key, value) pairs)."""
    return get_model(name, **dict(options_items))


def model_for(name: str, options: dict):
    """This process's model instance for name and options: the one its evaluations use."""
    return model_instance(name, tuple(sorted(options.items())))
