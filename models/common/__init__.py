"""The physics two or more models share: the planar tyre, rotations, chassis contact (superellipsoid geometry,
broad phase, force and friction laws), contact episodes and impact rows. Models build on this package and on
the framework (crashlab), never on each other (tests/test_architecture.py)."""
