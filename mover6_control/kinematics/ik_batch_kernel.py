"""
The batch closed-form IK's per-pose solve: one compiled loop over the poses (numba).

``ik_closed_form.ik_closed_form_batch`` (and ``solve_candidates``, which the path IK calls pose
after pose) solve each pose by the steps of that module's docstring: q1 (two roots), q3 (two
per q1), q2, then the wrist (two flips: q5, q4, q6), a branch dropped as soon as one of its
joints is unsolvable or (with ``within_limits``) outside its limits, and every branch left
checked by forward kinematics. As array operations on flat arrays of branches, the
interpreter's per-operation cost and the temporaries were most of the time (about 1 us a pose,
and a few hundred us for one pose); here the 8 branches of a pose are nested loops on floats,
compiled, run without the interpreter lock (``nogil``): about 0.5 us a pose on the bench's
Mover6 poses (the C library's ``atan2``, ``sincos`` and ``acos`` a third of it). The
constants come from ``ik_closed_form._plan`` (per wrist geometry) and
``ik_closed_form._fk_chain`` (per arm).

Each number is computed by the operations of the array formulation, in the same order (numba
contracts no multiply-add into a fused one while ``fastmath`` is off), except that the products
with the plan's matrices sum their terms in index order (the array version's BLAS products may
fuse multiply-adds) and ``sin``, ``cos``, ``acos``, ``atan2`` are the C library's (NumPy's
vectorised ones may differ in the last bit): the angles agree with the per-branch float
reference to rounding (``test/unit/kinematics/test_ik_batch_reference.py``).

The FK check multiplies out the URDF chain of ``forward`` (origin, then the turn about the
joint's axis; then the tool) on the sines and cosines found by the solve, entry by entry as
the matrices' products with their exact zeros and ones left out would: a turn about a frame
axis changes two columns, ``a cos + b s'`` and ``b cos - a s'`` (``s'`` the sine with the
axis's sign), another turn is Rodrigues' ``(I + sin K) + (1 - cos) K K`` multiplied in full,
and an origin that does not turn adds its translation only.

Compiled when this module is imported (the signature is given), from numba's on-disk cache
after the first time, as ``motion.timing.greedy_scan``.
"""

from __future__ import annotations

import math

import numba
import numpy as np


def _given(dtype, ndim):
    """Return the type of a C-contiguous input array (read-only ones accepted)."""
    return numba.types.Array(dtype, ndim, 'C', readonly=True)


_F1, _F2, _F3, _F4 = (_given(numba.float64, n) for n in (1, 2, 3, 4))
_I1, _I2 = _given(numba.int64, 1), _given(numba.int64, 2)
_SOLVE_SIGNATURE = numba.void(
    _F3, _F2, _I1, _I2, _F2, _F1, _F1, _F2, _F1, _F2, _F2, _F1, _F1, _F3, _F4,
    _given(numba.boolean, 1), _I1, numba.boolean, numba.float64, numba.float64,
    numba.float64[:, :, ::1], numba.boolean[:, ::1], numba.boolean[::1])


@numba.njit(cache=True, nogil=True, error_model='numpy')
def _alias(q, ref, lo, hi, within_limits):  # pragma: no cover (compiled)
    """
    Return ``q`` moved by whole turns nearest ``ref`` (and into [lo, hi]), and whether inside.

    ``ik_closed_form.nearest_alias`` for one angle: ``ref + wrap(q - ref)``, the wrap
    ``(x + pi) % 2 pi - pi`` taking the remainder only outside [0, 2 pi), then one more turn
    when that brings the angle inside the limits. Without ``within_limits`` always inside.
    """
    x = (q - ref) + math.pi
    if x < 0.0 or x >= math.tau:
        q = ref + (x % math.tau - math.pi)
    else:
        q = ref + (x - math.pi)
    if not within_limits:
        return q, True
    if q < lo:
        up = q + math.tau
        if up >= lo and up <= hi:
            q = up
    if q > hi:
        down = q - math.tau
        if down >= lo and down <= hi:
            q = down
    return q, q >= lo - 1e-9 and q <= hi + 1e-9


@numba.njit(cache=True, nogil=True, error_model='numpy')
def _cos_sin_of_atan2(y, x):  # pragma: no cover (compiled)
    """Return the cosine and sine of ``atan2(y, x)``: ``x / hypot``, ``y / hypot`` (1, 0 at 0)."""
    h = math.sqrt(x * x + y * y)
    if h == 0.0:
        h, x = 1.0, 1.0
    inv = 1.0 / h
    return x * inv, y * inv


@numba.njit(cache=True, nogil=True, error_model='numpy')
def _turn_back(w0, w1, w2, s, c, v0, v1, v2):  # pragma: no cover (compiled)
    """Return ``v`` turned by minus the angle of sine ``s``, cosine ``c`` about ``w``."""
    d = (w0 * v0 + w1 * v1 + w2 * v2) * (1.0 - c)
    return ((v0 * c - (w1 * v2 - w2 * v1) * s) + w0 * d,
            (v1 * c - (w2 * v0 - w0 * v2) * s) + w1 * d,
            (v2 * c - (w0 * v1 - w1 * v0) * s) + w2 * d)


@numba.njit(cache=True, nogil=True, error_model='numpy')
def _row_times(a0, a1, a2, M):  # pragma: no cover (compiled)
    """Return the row ``(a0, a1, a2) M`` (``M`` 3 x 3 row-major, 9 floats), in index order."""
    return ((a0 * M[0] + a1 * M[3]) + a2 * M[6], (a0 * M[1] + a1 * M[4]) + a2 * M[7],
            (a0 * M[2] + a1 * M[5]) + a2 * M[8])


@numba.njit(cache=True, nogil=True, error_model='numpy')
def _times(R, M):  # pragma: no cover (compiled)
    """Return ``R M`` of two 3 x 3 matrices as row-major 9-tuples."""
    x0, x1, x2 = _row_times(R[0], R[1], R[2], M)
    y0, y1, y2 = _row_times(R[3], R[4], R[5], M)
    z0, z1, z2 = _row_times(R[6], R[7], R[8], M)
    return (x0, x1, x2, y0, y1, y2, z0, z1, z2)


@numba.njit(cache=True, nogil=True, error_model='numpy')
def _turned_about(R, j, c, s):  # pragma: no cover (compiled)
    """
    Return ``R Rot(e_j, q)`` (row-major 9-tuples) of cosine ``c`` and signed sine ``s``.

    Columns ``a = j + 1`` and ``b = j + 2`` (mod 3) turn: ``a c + b s`` and ``a (-s) + b c``,
    what ``R`` times the rotation's matrix gives with its zeros and ones left out.
    """
    if j == 0:
        return (R[0], R[1] * c + R[2] * s, R[1] * -s + R[2] * c,
                R[3], R[4] * c + R[5] * s, R[4] * -s + R[5] * c,
                R[6], R[7] * c + R[8] * s, R[7] * -s + R[8] * c)
    if j == 1:
        return (R[2] * -s + R[0] * c, R[1], R[2] * c + R[0] * s,
                R[5] * -s + R[3] * c, R[4], R[5] * c + R[3] * s,
                R[8] * -s + R[6] * c, R[7], R[8] * c + R[6] * s)
    return (R[0] * c + R[1] * s, R[0] * -s + R[1] * c, R[2],
            R[3] * c + R[4] * s, R[3] * -s + R[4] * c, R[5],
            R[6] * c + R[7] * s, R[6] * -s + R[7] * c, R[8])


@numba.njit(cache=True, nogil=True, error_model='numpy')
def _off_arc(y, x, arc, j):  # pragma: no cover (compiled)
    """
    Return True when ``atan2(y, x)`` is surely outside joint ``j``'s limits, whole turns aside.

    ``arc[j]``: the cosine and sine of the range's middle m and the cosine of its half width h
    plus 1e-9 (the limit test's slack) plus 1e-7 (far above the rounding of this test and of
    ``atan2``), or -2 when that reaches pi (no angle is surely outside). The angle is at least
    h + 1e-7 from m (mod 2 pi) when ``cos(angle - m) < cos(h + 1e-7)``, and then no whole turn
    of it (``_alias``) is within the limits: the branch is dropped before its ``atan2``.
    """
    return x * arc[j, 0] + y * arc[j, 1] < arc[j, 2] * math.sqrt(x * x + y * y)


@numba.njit(_SOLVE_SIGNATURE, cache=True, nogil=True, error_model='numpy')
def solve_poses(T, q_ref, row_nnz, row_cols, row_vals, offset, k, elbow, w3, tv_basis,
                tx_basis, lo, hi, frames, turns, identity, axis_index, within_limits, tol2,
                chord2, Q, ok, used_ref):  # pragma: no cover (compiled)
    """
    Fill ``Q`` (m, 8, 6), ``ok`` (m, 8) and ``used_ref`` (m,) for the poses ``T`` (m, 4, 4).

    ``q_ref`` (m, 6); ``row_nnz``, ``row_cols``, ``row_vals`` (27, 12): the plan's ``rows``
    without their zeros (per row its number of nonzero entries, their columns and values, in
    column order: the same sums), ``offset`` (27,), ``elbow``, ``w3``, ``tv_basis``,
    ``tx_basis`` and ``k`` (phi3, rho3, safe rho3, half, sigma, s45, s56, den, |n45|^2, the six
    q5 constants) from ``ik_closed_form._plan``; ``lo``, ``hi`` (6,) the joint limits;
    ``frames``, ``turns``, ``identity``, ``axis_index``: the chain (``ik_closed_form._fk_chain``
    says what they hold); ``tol2``, ``chord2`` the FK check's bounds. ``Q`` and ``ok`` as
    ``ik_closed_form.solve_candidates`` returns them; ``used_ref`` marks the poses whose q1 or
    q4 came from ``q_ref``.
    """
    m = T.shape[0]
    X = np.empty(27)
    G = np.empty(6)
    turned = np.empty((2, 3))
    tv = np.empty(4)
    tx = np.empty(18)
    sc = np.empty(12)
    rot = np.empty((3, 3))
    phi3, rho3, safe3, half, sigma = k[0], k[1], k[2], k[3], k[4]
    arc = np.empty((6, 3))
    for j in range(6):
        half_width = 0.5 * (hi[j] - lo[j]) + 1e-9 + 1e-7
        middle = 0.5 * (lo[j] + hi[j])
        arc[j, 0], arc[j, 1] = math.cos(middle), math.sin(middle)
        arc[j, 2] = math.cos(half_width) if within_limits and half_width < math.pi else -2.0
    s45, s56, den, nn45 = k[5], k[6], k[7], k[8]
    for i in range(m):
        ref0, ref1, ref2 = q_ref[i, 0], q_ref[i, 1], q_ref[i, 2]
        ref3, ref4, ref5 = q_ref[i, 3], q_ref[i, 4], q_ref[i, 5]
        used_ref[i] = False
        for branch in range(8):
            ok[i, branch] = False
            for j in range(6):
                Q[i, branch, j] = q_ref[i, j]
        for r in range(27):
            acc = 0.0
            for t in range(row_nnz[r]):
                col = row_cols[r, t]
                acc += row_vals[r, t] * T[i, col >> 2, col & 3]
            X[r] = acc + offset[r]
        # q1 (two roots): a cos q1 + b sin q1 = c.
        ea, eb, ec = X[0], X[1], X[2]
        rho = math.sqrt(ea * ea + eb * eb)
        ok1 = abs(ec) <= rho + 1e-12
        delta = math.acos(min(max(ec / (rho if rho > 1e-12 else 1.0), -1.0), 1.0))
        phi = math.atan2(eb, ea)
        q1_roots = (phi + delta, phi - delta)
        if rho < 1e-9:                                        # shoulder singularity
            q1_roots = (ref0, ref0)
            ok1 = ok1 or abs(ec) < 1e-9
            used_ref[i] = True
        if not ok1:
            continue
        for r1 in range(2):
            q1 = q1_roots[r1]
            q1a, inside = _alias(q1, ref0, lo[0], hi[0], within_limits)
            if not inside:
                continue
            s1, c1 = math.sin(q1), math.cos(q1)
            sc[0], sc[1] = s1, c1
            # q3 (two roots): the wrist centre's distance to axis 2, law of cosines.
            dx = (X[3] + c1 * X[4]) + s1 * X[5]
            dy = (X[6] + c1 * X[7]) + s1 * X[8]
            rhs = 0.5 * (dx * dx + dy * dy) - half
            if not abs(rhs) <= rho3 + 1e-12:
                continue
            acos3 = math.acos(min(max(rhs / safe3, -1.0), 1.0))
            # The goal's two axes turned back by q1, in the basis (e1, e2, w2) of the plane.
            for g in range(6):
                G[g] = (X[9 + 3 * g] + c1 * X[10 + 3 * g]) + s1 * X[11 + 3 * g]
            for r3 in range(2):
                q3 = phi3 + acos3 if r3 == 0 else phi3 - acos3
                q3a, inside = _alias(q3, ref2, lo[2], hi[2], within_limits)
                if not inside:
                    continue
                s3, c3 = math.sin(q3), math.cos(q3)
                sc[4], sc[5] = s3, c3
                # q2 turns x - r2 (x: the wrist centre turned by q3) onto d, in the plane.
                ux = (elbow[0, 0] + c3 * elbow[0, 1]) + s3 * elbow[0, 2]
                uy = (elbow[1, 0] + c3 * elbow[1, 1]) + s3 * elbow[1, 2]
                y2 = ux * dy - uy * dx
                x2 = ux * dx + uy * dy
                if _off_arc(y2, x2, arc, 1):
                    continue
                q2a, inside = _alias(math.atan2(y2, x2), ref1, lo[1], hi[1], within_limits)
                if not inside:
                    continue
                c2, s2 = _cos_sin_of_atan2(y2, x2)
                sc[2], sc[3] = s2, c2
                # The goal's axes turned back by q2 and q3 too.
                if sigma != 0.0:
                    cq, sq = c2 * c3 - sigma * s2 * s3, s2 * c3 + sigma * c2 * s3
                else:
                    cq, sq = c2, s2
                for t in range(2):
                    x, y, z = G[3 * t], G[3 * t + 1], G[3 * t + 2]
                    x, y = x * cq + y * sq, y * cq - x * sq
                    if sigma == 0.0:
                        x, y, z = _turn_back(w3[0], w3[1], w3[2], s3, c3, x, y, z)
                    turned[t, 0], turned[t, 1], turned[t, 2] = x, y, z
                for t in range(4):
                    tv[t] = ((tv_basis[t, 0] * turned[0, 0] + tv_basis[t, 1] * turned[0, 1])
                             + tv_basis[t, 2] * turned[0, 2])
                for t in range(18):
                    tx[t] = ((tx_basis[t, 0] * turned[1, 0] + tx_basis[t, 1] * turned[1, 1])
                             + tx_basis[t, 2] * turned[1, 2])
                # The wrist: z = alpha w4 + beta w5 +- gamma n45 (subproblem 2), q5 then q4.
                a4, a5, an, am = tv[0], tv[1], tv[2], tv[3]
                alpha = (s45 * s56 - a4) / den
                beta = (s45 * a4 - s56) / den
                gamma2 = (1.0 - alpha * alpha - beta * beta - 2.0 * alpha * beta * s45) / nn45
                gamma = math.sqrt(max(gamma2, 0.0))
                singular = math.sqrt((beta * beta + gamma * gamma) * nn45) < 1e-9
                if singular:
                    used_ref[i] = True
                if not gamma2 > -1e-9:
                    continue
                for flip in range(2):
                    g = gamma if flip == 0 else -gamma
                    y5 = (alpha * k[9] + beta * k[10]) + g * k[11]
                    x5 = (alpha * k[12] + beta * k[13]) + g * k[14]
                    if _off_arc(y5, x5, arc, 4):
                        continue
                    q5a, inside = _alias(math.atan2(y5, x5), ref4, lo[4], hi[4],
                                         within_limits)
                    if not inside:
                        continue
                    if singular:
                        y4, x4, q4 = math.sin(ref3), math.cos(ref3), ref3
                    else:
                        y4 = beta * an + g * am
                        x4 = beta * (a5 - s45 * a4) + g * an
                        if _off_arc(y4, x4, arc, 3):
                            continue
                        q4 = math.atan2(y4, x4)
                    q4a, inside = _alias(q4, ref3, lo[3], hi[3], within_limits)
                    if not inside:
                        continue
                    c5, s5 = _cos_sin_of_atan2(y5, x5)
                    c4, s4 = _cos_sin_of_atan2(y4, x4)
                    # q6 from two dot products of the turned R_w x6 (``_q6_basis``).
                    h0 = (tx[0] + c5 * tx[1]) + s5 * tx[2]
                    h1 = (tx[3] + c5 * tx[4]) + s5 * tx[5]
                    h2 = (tx[6] + c5 * tx[7]) + s5 * tx[8]
                    h3 = (tx[9] + c5 * tx[10]) + s5 * tx[11]
                    h4 = (tx[12] + c5 * tx[13]) + s5 * tx[14]
                    h5 = (tx[15] + c5 * tx[16]) + s5 * tx[17]
                    y6, x6 = (h0 + c4 * h1) + s4 * h2, (h3 + c4 * h4) + s4 * h5
                    if _off_arc(y6, x6, arc, 5):
                        continue
                    q6a, inside = _alias(math.atan2(y6, x6), ref5, lo[5], hi[5],
                                         within_limits)
                    if not inside:
                        continue
                    c6, s6 = _cos_sin_of_atan2(y6, x6)
                    sc[6], sc[7], sc[8], sc[9], sc[10], sc[11] = s4, c4, s5, c5, s6, c6
                    branch = 4 * r1 + 2 * r3 + flip
                    Q[i, branch, 0], Q[i, branch, 1], Q[i, branch, 2] = q1a, q2a, q3a
                    Q[i, branch, 3], Q[i, branch, 4], Q[i, branch, 5] = q4a, q5a, q6a
                    # The FK check: the chain multiplied out (the module docstring).
                    Rt = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
                    pt = (0.0, 0.0, 0.0)
                    for f in range(7):
                        t0, t1, t2 = frames[f, 0, 3], frames[f, 1, 3], frames[f, 2, 3]
                        pt = (((pt[0] + Rt[0] * t0) + Rt[1] * t1) + Rt[2] * t2,
                              ((pt[1] + Rt[3] * t0) + Rt[4] * t1) + Rt[5] * t2,
                              ((pt[2] + Rt[6] * t0) + Rt[7] * t1) + Rt[8] * t2)
                        if not identity[f]:
                            Rt = _times(Rt, (frames[f, 0, 0], frames[f, 0, 1], frames[f, 0, 2],
                                             frames[f, 1, 0], frames[f, 1, 1], frames[f, 1, 2],
                                             frames[f, 2, 0], frames[f, 2, 1], frames[f, 2, 2]))
                        if f == 6:
                            break
                        sf, cf = sc[2 * f], sc[2 * f + 1]
                        j = axis_index[f]
                        if j >= 0:                  # a frame axis: two columns turn
                            sign = turns[f, 1, (j + 2) % 3, (j + 1) % 3]
                            Rt = _turned_about(Rt, j, cf, sign * sf)
                            continue
                        w = 1.0 - cf
                        for u in range(3):
                            for v in range(3):
                                rot[u, v] = ((turns[f, 0, u, v] + turns[f, 1, u, v] * sf)
                                             + turns[f, 2, u, v] * w)
                        Rt = _times(Rt, (rot[0, 0], rot[0, 1], rot[0, 2], rot[1, 0], rot[1, 1],
                                         rot[1, 2], rot[2, 0], rot[2, 1], rot[2, 2]))
                    position, chord = 0.0, 0.0
                    for u in range(3):
                        d = pt[u] - T[i, u, 3]
                        position += d * d
                        for v in range(3):
                            d = Rt[3 * u + v] - T[i, u, v]
                            chord += d * d
                    ok[i, branch] = position < tol2 and chord < chord2
