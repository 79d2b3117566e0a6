"""An example third-party collision model for crashlab, registered under the name `example` through the
entry-point group `crashlab.models` (pyproject.toml of this folder)."""
from .model import ExampleModel

__all__ = ["ExampleModel"]
