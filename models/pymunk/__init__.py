"""Planar rigid-body engine model (Chipmunk2D via pymunk); pymunk itself is imported only by `simulate`."""
from .model import PymunkModel

__all__ = ["PymunkModel"]
