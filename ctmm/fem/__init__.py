"""Finite-element and global-equation subsystems coupled to planar transfer systems (mixed MSTMM).

* :mod:`ctmm.fem.elements` -- planar Euler-Bernoulli beam elements (consistent mass, stiffness,
  geometric stiffness; the Timoshenko option of :mod:`ctmm.fem.timoshenko`), point masses, spring-dampers
  between nodes;
* :mod:`ctmm.fem.assembly` -- :class:`FiniteElementModel`: named nodes, assembled ``M, C, K`` (Rayleigh
  damping), floating-frame inertia integrals by quadrature;
* :mod:`ctmm.fem.subsystem` -- :class:`GlobalSubsystem`: a subsystem given by global equations
  ``M u'' + C u' + K u = f(u, u', t)`` as a body of :class:`ctmm.planar.PlanarModel` (floating frame
  at its inboard boundary node; outboard boundary nodes are its points), so every planar verb
  (``ctmm.simulate`` with RK4, solve_ivp and the DT-TMM schemes, ``ctmm.linearize``,
  ``ctmm.frequency_response``, ``ctmm.natural_frequencies``) runs on the mixed system;
* spatial counterparts (``docs/mixed.md`` §7): :mod:`ctmm.fem.spatial_elements` (12-DOF beam, point mass with
  inertia, node spring), :mod:`ctmm.fem.spatial_plate` (rectangular ACM plate with membrane action),
  :mod:`ctmm.fem.spatial_assembly` (:class:`SpatialFiniteElementModel`),
  :mod:`ctmm.fem.spatial_subsystem` (:class:`SpatialSubsystem`, a body of :class:`ctmm.spatial.SpatialModel`
  with ``d = 6`` boundary points; its terms in :mod:`ctmm.fem.spatial_terms`);
* flat shells of any shape (``docs/mixed.md`` §7d): :mod:`ctmm.fem.thick_plate` (Mindlin MITC4 quadrilateral),
  :mod:`ctmm.fem.triangle_plate` (DKT triangle), their shared parts in :mod:`ctmm.fem.flat_shell`.

Derivation and validation: ``docs/mixed.md``.
"""
from .assembly import FiniteElementModel
from .elements import BeamElement, NodeSpring, PointMass, beam_local_matrices
from .family import SmallDeformationWarning, SubsystemFamily, subsystem_energy
from .membrane import MembraneElement
from .subsystem import FloatingInertia, GlobalSubsystem
from .spatial_assembly import SpatialFiniteElementModel
from .spatial_elements import SpatialBeamElement, SpatialNodeSpring, SpatialPointMass
from .spatial_plate import SpatialPlateElement
from .spatial_subsystem import SpatialInertia, SpatialSubsystem
from .thick_plate import SpatialThickPlateElement
from .triangle_plate import SpatialTrianglePlateElement

__all__ = ["FiniteElementModel", "BeamElement", "MembraneElement", "PointMass", "NodeSpring", "beam_local_matrices", "GlobalSubsystem",
           "FloatingInertia", "SubsystemFamily", "SmallDeformationWarning", "subsystem_energy",
           "SpatialFiniteElementModel", "SpatialBeamElement", "SpatialPointMass", "SpatialNodeSpring", "SpatialInertia",
           "SpatialPlateElement",
           "SpatialSubsystem", "SpatialThickPlateElement", "SpatialTrianglePlateElement"]
