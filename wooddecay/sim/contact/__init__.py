"""Contact between detached components and against colliders (woodstock §5.4, Eqs. 3-7; docs/model.md §4).

Rod element i is a capsule of radius r_i around the segment from particle ``first_particle[i]`` to
``first_particle[i] + 1``. Capsules of different components repel with the quadratic penalty of
Eqs. 3-4, applied as an implicit (XPBD) step; colliders push particles out the same way; friction
(Eqs. 5-7) acts on positions after all normal steps; contacts end inelastic (restitution 0).

- :mod:`.closest`: closest points of two segments or a point and a segment, and the normal and
  penetration of two capsules (Eq. 3);
- :mod:`.broadphase`: the element pairs within reach, from a hash grid swept along one axis;
- :mod:`.capsules`: the Jacobi XPBD projection of the pairs (Eq. 4), their depenetration and
  inelastic velocities. Rest overlap: capsules of neighbouring strands overlap in the intact wood,
  and a pair's penetration counts only beyond its overlap at the rest positions;
- :mod:`.friction`: Eq. 7 on the displacement of the substep;
- :mod:`.colliders`: plane, box, sphere and cylinder obstacles (:func:`collider_row`).

Every parallel loop writes only its own element, pair or particle, and sums over a particle's
contacts run in a fixed order: results are bit-identical for any thread count. Each kernel's plain
numpy/scipy twin, ``*_reference``, lives beside it in the same module; the tests compare against it.
"""
from .broadphase import KEPT, candidate_pairs, candidate_pairs_reference
from .capsules import (
    contact_velocities,
    contact_velocities_reference,
    pair_overlaps,
    project_contacts,
    project_contacts_reference,
)
from .closest import (
    capsule_contact,
    closest_point_segment,
    closest_segment_segment,
    closest_segment_segment_reference,
)
from .colliders import (
    BOX,
    COLLIDER_COLUMNS,
    CYLINDER,
    PLANE,
    SPHERE,
    check_colliders,
    collider_distance,
    collider_row,
    collider_velocities,
    collider_velocities_reference,
    project_colliders,
    project_colliders_reference,
)
from .friction import particle_friction, particle_friction_reference

__all__ = ["BOX", "COLLIDER_COLUMNS", "CYLINDER", "KEPT", "PLANE", "SPHERE", "candidate_pairs",
           "candidate_pairs_reference", "capsule_contact", "check_colliders", "closest_point_segment",
           "closest_segment_segment", "closest_segment_segment_reference", "collider_distance", "collider_row",
           "collider_velocities", "collider_velocities_reference", "contact_velocities",
           "contact_velocities_reference", "pair_overlaps", "particle_friction", "particle_friction_reference",
           "project_colliders", "project_colliders_reference", "project_contacts", "project_contacts_reference"]
