"""World frames of every joint of a Pinocchio model for many configurations at once (vectorised FK),
with products by constant or sparse matrices written out term by term.

:class:`JointChain` reads the model's joints (parent, placement (M, p) in the parent, motion axis)
once. For a block of N configurations it computes every joint's world rotation and translation,
``R_j = R_parent L_j`` and ``t_j = R_parent p + t_parent`` (a prismatic joint adds its axis times
q to p), with numpy over the block, where ``L_j = M + sin q MK + (1 - cos q) MK^2`` (Rodrigues'
formula, K = [axis]x; zero for prismatic joints). Entries of L_j where MK and MK^2 vanish are the
constants of M; each other distinct entry is one (N,) vector. Each column of R_j is then the sum,
over the nonzero entries of L_j's column, of a parent column times that entry: zero entries
skipped, +-1 as a sign, terms in order. That is the plain 3x3 product's sum bit for bit (up to the
sign of a zero) at a fraction of its arithmetic: arm joints' placements are near quarter turns, so
L_j has few nonzero entries and several exact ones.

:func:`constant_product` (the sum of a matrix's columns times coefficients, as above) also serves
the geometry placements (:mod:`.placements`). Checked against Pinocchio in tests/test_kernel.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..errors import ParameterError

__all__ = ["JointChain", "KernelUnsupported", "constant_product", "product_terms"]

FloatArray = npt.NDArray[np.float64]


class KernelUnsupported(ParameterError):
    """The World holds a joint type the vectorised kinematics does not model."""


@dataclass(frozen=True, slots=True)
class _Joint:
    """One joint: parent, placement in the parent, motion kind and axis, index in q."""

    parent: int
    R: FloatArray  # placement rotation (3, 3)
    p: FloatArray  # placement translation (3,)
    revolute: bool
    axis: FloatArray  # unit axis in the joint frame (3,)
    iq: int


def _joint_of(jm, parent: int, M) -> _Joint:
    name = jm.shortname()
    R = np.array(M.rotation, dtype=np.float64)
    p = np.array(M.translation, dtype=np.float64)
    for k, ax in enumerate("XYZ"):
        if name in (f"JointModelR{ax}", f"JointModelP{ax}"):
            return _Joint(parent, R, p, name[10] == "R", np.eye(3)[k], int(jm.idx_q))
    if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = np.array(jm.extract().axis, dtype=np.float64)
        return _Joint(parent, R, p, "Revolute" in name, axis / np.linalg.norm(axis), int(jm.idx_q))
    raise KernelUnsupported(f"joint type {name} is not modelled by the vectorised kinematics")


def product_terms(v) -> list[tuple[int, object, int]]:
    """The nonzero terms of a product by a constant (3,) vector, or by three coefficients (floats,
    or keys of varying ones): (k, coefficient, sign), sign +-1 where the coefficient is +-1 (a copy
    or a sign), else 0; in order k = 0, 1, 2."""
    out = []
    for k, c in enumerate(v):
        if isinstance(c, float | np.floating):
            if c != 0.0:
                out.append((k, float(c), int(c) if abs(c) == 1.0 else 0))
        else:
            out.append((k, c, 0))
    return out


def constant_product(X: FloatArray, terms: list, out: FloatArray, tmp: FloatArray) -> None:
    """``out = sum X[k] * c`` over :func:`product_terms`' terms (k, c, sign), c resolved to a float or
    an (n,) array, for X (3, 3, n) indexed by column first: in order, +-1 as a sign (so the sum is
    the plain one's bit for bit, up to the sign of a zero). ``tmp`` (3, n) is scratch; no terms:
    zeros."""
    if not terms:
        out[...] = 0.0
        return
    k, c, _ = terms[0]
    np.multiply(X[k], c, out=out)  # exact for +-1
    for k, c, sign in terms[1:]:
        if sign > 0:
            np.add(out, X[k], out=out)
        elif sign < 0:
            np.subtract(out, X[k], out=out)
        else:
            np.multiply(X[k], c, out=tmp)
            np.add(out, tmp, out=out)


class JointChain:
    """The joints of a Pinocchio model and their world frames for blocks of configurations (see the
    module docstring).

    Args:
        model: the Pinocchio model (read once).

    Raises:
        KernelUnsupported: a joint other than revolute/prismatic (x, y, z or an unaligned axis).
    """

    def __init__(self, model) -> None:
        self.nq = int(model.nq)
        J = self.joints = [
            _joint_of(model.joints[j], int(model.parents[j]), model.jointPlacements[j]) for j in range(1, model.njoints)
        ]
        self._jq = np.array([j.iq for j in J], dtype=np.int64)
        # per joint: the distinct varying entries of L = M + sin q MK + (1 - cos q) MK^2 as constants
        # (MK, MK^2, M), and per column of L its terms: constants, or indices into those entries
        self._entries: list[list[tuple[float, float, float]]] = []
        self._cols: list[list] = []
        for j in J:
            K = np.cross(np.eye(3), j.axis) * j.revolute
            MK, MK2 = j.R @ K, j.R @ K @ K
            entries: list[tuple[float, float, float]] = []
            cols = []
            for col in range(3):
                coef: list = []
                for k in range(3):
                    e = (float(MK[k, col]), float(MK2[k, col]), float(j.R[k, col]))
                    if e[0] == 0.0 and e[1] == 0.0:
                        coef.append(e[2])
                    else:
                        if e not in entries:
                            entries.append(e)
                        coef.append(entries.index(e))
                cols.append(product_terms(coef))
            self._entries.append(entries)
            self._cols.append(cols)
        self._p_terms = [product_terms(j.p) for j in J]

    def compute(self, Q: FloatArray, buf) -> tuple[FloatArray, FloatArray]:
        """World rotations by column, (nj, 3, 3, n) with ``[j, k]`` column k (3, n) of joint j's, and
        translations (nj, 3, n) of every joint (index 0: the universe) for joints Q (n, nq) [rad]
        (trusted input); views of ``buf``'s arrays."""
        n = Q.shape[0]
        nj = len(self.joints) + 1
        JC = buf("JC", (nj, 3, 3, n))
        Jt = buf("Jt", (nj, 3, n))
        JC[0] = np.eye(3)[:, :, None]
        Jt[0] = 0.0
        q = Q[:, self._jq].T  # (J, n)
        sin, vers = buf("j_sin", q.shape), buf("j_vers", q.shape)
        np.sin(q, out=sin)
        np.cos(q, out=vers)
        np.subtract(1.0, vers, out=vers)  # 1 - cos q
        tmp3 = buf("j_tmp", (3, n))
        ent = buf("j_ent", (9, n))
        t1 = buf("j_t1", (n,))
        for i, (Jn, entries, cols, p_terms) in enumerate(zip(self.joints, self._entries, self._cols, self._p_terms)):
            j, par = i + 1, JC[Jn.parent]
            for m, (a, b, c) in enumerate(entries):  # ((sin q a) + ((1 - cos q) b)) + c, exact zeros skipped
                e = ent[m]
                if a != 0.0 and b != 0.0:
                    np.multiply(sin[i], a, out=e)
                    np.multiply(vers[i], b, out=t1)
                    e += t1
                elif a != 0.0:
                    np.multiply(sin[i], a, out=e)
                else:
                    np.multiply(vers[i], b, out=e)
                if c != 0.0:
                    e += c
            for k, terms in enumerate(cols):
                constant_product(par, [(m, c if isinstance(c, float) else ent[c], sg) for m, c, sg in terms],
                                 JC[j, k], tmp3)
            if Jn.revolute:
                constant_product(par, p_terms, Jt[j], tmp3)
            else:
                tl = Jn.p[:, None] + np.multiply.outer(Jn.R @ Jn.axis, Q[:, Jn.iq])
                np.einsum("lin,ln->in", par, tl, out=Jt[j])
            Jt[j] += Jt[Jn.parent]
        return JC, Jt
