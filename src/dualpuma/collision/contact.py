"""Self-contact of a World's arms on their meshes: the contact maps of both arms
(:mod:`dualpuma.model.contact`) asked about configurations and about the motions between them.

* :func:`self_contact` — per configuration, the first close pair (side, a, b) that may be within
  :data:`~dualpuma.model.contact.CONTACT_CLEARANCE` of contact, or None.
* :func:`first_contact_chord` — the first motion between consecutive configurations that may bring
  one there (the planners' and the timing's certificates refuse it: :mod:`dualpuma.planning.certify`).

The maps are kept in the World's :class:`~dualpuma.model.cache.WorldCache`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..checks import instance, validate_joints
from ..errors import JointError
from ..model.contact import CONTACT_CLEARANCE, ContactMap, contact_maps
from ..model.world import World

__all__ = ["contact_reason", "first_contact_chord", "self_contact", "unmapped_sides"]

FloatArray = npt.NDArray[np.float64]
_KEY = "collision.contact"
_SIDES = ("left", "right")


def _maps(world: World) -> tuple[tuple[tuple[str, int, ContactMap], ...], tuple[str, ...]]:
    """((side, joint offset in the World's q, map) for every mapped pair, the sides whose close
    pairs have no map)."""

    def build():
        entries, unmapped = [], []
        for k, s in enumerate(_SIDES):
            maps = contact_maps(world.arms[s])
            if maps is None:
                unmapped.append(s)
                continue
            entries += [(s, 6 * k, m) for m in maps]
        return tuple(entries), tuple(unmapped)

    return world.cache.shared(_KEY, build)


def unmapped_sides(world: World) -> tuple[str, ...]:
    """The sides of ``world`` whose arm has close pairs two joints apart without a contact map
    (their meshes are not checked: ``docs/robots.md``)."""
    instance(world, World, "world")
    return _maps(world)[1]


def contact_reason(side: str, a: str, b: str) -> str:
    """How a refusal names a close pair."""
    return f"{side} arm {a} – {b}: their meshes may come within {CONTACT_CLEARANCE * 1e3:g} mm (self-contact)"


def self_contact(world: World, Q_left: npt.ArrayLike, Q_right: npt.ArrayLike) -> list[tuple[str, str, str] | None]:
    """Per configuration (rows of Q_left, Q_right (N, 6) or one (6,) each [rad]): the first close
    pair ``(side, a, b)`` in a blocked cell of its contact map, or None.

    Raises:
        JointError: malformed joints. ParameterError: ``world`` is not a World.
    """
    instance(world, World, "world")
    QL = validate_joints(Q_left, name="Q_left").reshape(-1, 6)
    QR = validate_joints(Q_right, name="Q_right").reshape(-1, 6)
    if QL.shape != QR.shape:
        raise JointError(f"Q_left and Q_right differ in shape: {QL.shape} vs {QR.shape}")
    out: list[tuple[str, str, str] | None] = [None] * QL.shape[0]
    for s, _, m in _maps(world)[0]:
        for i in np.flatnonzero(m.blocked(QL if s == "left" else QR)).tolist():
            if out[i] is None:
                out[i] = (s, m.a, m.b)
    return out


def first_contact_chord(world: World, Q: FloatArray) -> tuple[int, str]:
    """Trusted configurations Q (n + 1, 12) (left then right joints) [rad]: the first motion
    ``i`` (from Q[i] to Q[i + 1], no joint turning back) that may bring a close pair within the
    contact clearance, and why; (n, "") when none may."""
    n = Q.shape[0] - 1
    best, why = n, ""
    if n <= 0:
        return best, why
    for s, off, m in _maps(world)[0]:
        hit = np.flatnonzero(m.box_blocked(Q[:-1, off : off + 6], Q[1:, off : off + 6]))
        if hit.size and int(hit[0]) < best:
            best, why = int(hit[0]), contact_reason(s, m.a, m.b)
    return best, why
