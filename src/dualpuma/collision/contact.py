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
from ..kinematics.bar_path import hold_bar
from ..kinematics.dual import SIDES, bar_poses
from ..lie import slerp_pairs
from ..model.contact import CONTACT_CLEARANCE, ContactMap, contact_maps
from ..model.world import World

__all__ = ["PATH_PAD", "PATH_PIECES", "contact_reason", "first_contact_chord", "self_contact", "unmapped_sides"]

FloatArray = npt.NDArray[np.float64]
_KEY = "collision.contact"
#: the bar's path between two configurations is followed at this many pieces (closed chain)
PATH_PIECES = 8
#: cells each piece's box is grown by on every side: a joint may turn back inside a piece (measured
#: overshoot on the planners' steps: docs/planner.md)
PATH_PAD = 1


def _maps(world: World) -> tuple[tuple[tuple[str, int, ContactMap], ...], tuple[str, ...]]:
    """((side, joint offset in the World's q, map) for every mapped pair, the sides whose close
    pairs have no map)."""

    def build():
        entries, unmapped = [], []
        for k, s in enumerate(SIDES):
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
    return f"{side}/{a} – {side}/{b}: their meshes may come within {CONTACT_CLEARANCE * 1e3:g} mm (self-contact)"


def self_contact(world: World, Q_left: npt.ArrayLike, Q_right: npt.ArrayLike) -> list[tuple[str, str, str] | None]:
    """Per configuration (rows of Q_left, Q_right (N, 6) or one (6,) each [rad]): the first close
    pair ``(side, a, b)`` in a blocked cell of its contact map, or None.

    Raises:
        JointError: malformed joints. ParameterError: ``world`` is not a World.
    """
    instance(world, World, "world")
    QL, QR = validate_joints(Q_left, name="Q_left"), validate_joints(Q_right, name="Q_right")
    if QL.ndim > 2 or QR.ndim > 2:
        raise JointError(f"Q_left, Q_right: expected shape (N, 6) or (6,), got {QL.shape}, {QR.shape}")
    QL, QR = QL.reshape(-1, 6), QR.reshape(-1, 6)
    if QL.shape != QR.shape:
        raise JointError(f"Q_left and Q_right differ in shape: {QL.shape} vs {QR.shape}")
    out: list[tuple[str, str, str] | None] = [None] * QL.shape[0]
    for s, _, m in _maps(world)[0]:
        for i in np.flatnonzero(m.blocked(QL if s == "left" else QR)).tolist():
            if out[i] is None:
                out[i] = (s, m.a, m.b)
    return out


def first_contact_chord(world: World, Q: FloatArray, closed_chain: bool = False) -> tuple[int, str]:
    """Trusted configurations Q (n + 1, 12) (left then right joints) [rad]: the first motion ``i``
    from Q[i] to Q[i + 1] that may bring a close pair within the contact clearance, and why; (n, "")
    when none may.

    The motion is the joint chord (a joint controller's, between samples: no joint turns back, so it
    stays in the box its ends span), or with ``closed_chain`` the arms holding the bar along its
    geodesic between the poses they hold it at (the planners' steps), on which a joint can turn
    back: that path is solved at :data:`PATH_PIECES` pieces (:func:`~dualpuma.kinematics.bar_path.hold_bar`),
    each piece's box grown by :data:`PATH_PAD` cells, and a piece the arms cannot hold is refused."""
    n = Q.shape[0] - 1
    maps = _maps(world)[0]
    if n <= 0 or not maps:
        return n, ""
    A, B, owner = Q[:-1], Q[1:], np.arange(n)
    best, why, pad = n, "", 0
    if closed_chain:
        k = PATH_PIECES
        poses = bar_poses(world, Q)
        cs, f = np.repeat(np.arange(n), k - 1), np.tile(np.arange(1, k) / k, n)
        inner, held = hold_bar(world, slerp_pairs(poses[cs], poses[cs + 1], f), Q[cs] + f[:, None] * (Q[cs + 1] - Q[cs]))
        path = np.empty((n, k + 1, 12))
        path[:, 0], path[:, 1:k], path[:, k] = Q[:-1], inner.reshape(n, k - 1, 12), Q[1:]
        A, B, owner, pad = path[:, :-1].reshape(-1, 12), path[:, 1:].reshape(-1, 12), np.repeat(np.arange(n), k), PATH_PAD
        lost = np.flatnonzero(~held)
        if lost.size:
            best, why = int(cs[lost[0]]), "on the bar's path the arms cannot hold it within their reach and joint limits"
    for s, off, m in maps:
        hit = np.flatnonzero(m.box_blocked(A[:, off : off + 6], B[:, off : off + 6], pad))
        if hit.size and int(owner[hit[0]]) < best:
            best, why = int(owner[hit[0]]), contact_reason(s, m.a, m.b)
    return best, why
