"""Multi-objective optimizers for crashlab, registered as ``crashlab.optimizers`` entry points.

* ``nsga_sharing.NSGASharing``: the thesis's NSGA with fitness sharing (Srinivas & Deb 1994);
  its pieces live in ``sharing``, ``selection`` and ``polynomial_mutation``.
* ``pymoo_algorithms``: pymoo's NSGA2, NSGA3, MOEAD, SMSEMOA and AGEMOEA behind one factory.

The collision repair and the least-squares polish live with the reconstruction
(crashlab.reconstruction.repair, .polish).

Nothing is imported here, so importing the package does not import pymoo.
"""
