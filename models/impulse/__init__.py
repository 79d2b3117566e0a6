"""Planar impulse-momentum collision model (Kudlich-Slibar as PC-Crash, or Brach)."""
from .model import ImpulseModel

__all__ = ["ImpulseModel"]
