"""3D multibody vehicle model (thesis chapter 2): rigid bodies with Euler parameters, joints,
Baumgarte-stabilised Lagrange multipliers, spring-dampers, UA tyres, adaptive Dormand-Prince."""
from .model import MultibodyModel

__all__ = ["MultibodyModel"]
