"""Model `exudyn`: the multibody model's 9-body vehicle built in exudyn (see README.md). exudyn itself is
imported only when a simulation is built, not by this import."""
from .model import ExudynModel

__all__ = ["ExudynModel"]
