"""The ICP engine of :mod:`swath.scan.register`: trimmed point-to-plane steps, scoring and
choice of the distinct poses, and the result with its uncertainty."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from ..errors import InfeasibleError
from .register_result import Registration, rotation_angle
from .register_settings import (
    _MOTION_NAMES,
    AMBIGUOUS_SCORE,
    COARSE_BOUND,
    COARSE_ITERATIONS,
    COARSE_KEEP,
    COARSE_POINTS,
    COARSE_SPACING,
    DEGENERATE_EIGENVALUE,
    FAR_FRACTION,
    FREEZE_AFTER,
    GATE_FLOOR,
    GATE_SIGMAS,
    MAX_STEP_ANGLE,
    NO_MATCH,
    POLISH_FROM,
    POOR_INLIERS,
    POOR_RMS,
    SAME_POSE_ANGLE,
    SAME_POSE_SHIFT,
    SEARCH_FACTOR,
    SETTLE_STEP,
)
from .register_target import _Source

log = logging.getLogger("swath.scan")
# --------------------------------------------------------------------------------------------
# the engine
# --------------------------------------------------------------------------------------------
def _register(src, tgt, starts, basis, *, trim, max_iterations, tolerance, inlier_distance,
              min_inlier_fraction, max_normal_angle, require_convergence, boundary, rng):
    cos_max = float(np.cos(max_normal_angle))
    opts = dict(basis=basis, trim=trim, cos_max=cos_max, boundary=boundary)
    # --- coarse: a few cheap steps from every start pose on a small subsample, then score
    if len(starts) > 1:
        sub = _subset(src, COARSE_POINTS, rng)
        sparse = tgt.thinned(COARSE_SPACING * src.size)
        mats, *_ = _icp(sub, sparse, starts, iterations=COARSE_ITERATIONS, tolerance=tolerance, exact=False,
                        check=False, bound=COARSE_BOUND * src.size, **opts)
        # the coarse poses have not converged, and a perimeter that is nearly symmetric can make a
        # turned pose look better than a true one that is still on its way: keep the best by the
        # surface alone and, on a table, the best with the perimeter too
        scores = _score(sub, sparse, mats, trim, cos_max, None, exact=False)
        chosen = list(_distinct(mats, np.argsort(scores), src, COARSE_KEEP))
        if boundary is not None:
            with_perimeter = _score(sub, sparse, mats, trim, cos_max, boundary, exact=False)
            for i in _distinct(mats, np.argsort(with_perimeter), src, COARSE_KEEP):
                if all(not _same_pose(mats[i], mats[j], src) for j in chosen):
                    chosen.append(int(i))
        log.info("registration: %d start poses; refining %d, coarse scores %s mm", len(starts), len(chosen),
                 np.round(1e3 * scores[chosen], 3).tolist())
        starts = mats[chosen]
    # --- fine: trimmed point-to-plane ICP to convergence from the best distinct poses (to a looser
    # tolerance when the exact polish follows)
    fine_tol = max(tolerance, POLISH_FROM * src.size) if tgt.surface is not None else tolerance
    mats, iters, conv, step, free = _icp(src, tgt, starts, iterations=max_iterations, tolerance=fine_tol,
                                         exact=False, check=True, **opts)
    if (free != "").all():
        raise InfeasibleError(_unconstrained_message(free[0]))
    fits = np.where(free != "", np.inf, _score(src, tgt, mats, trim, cos_max, boundary, exact=True))
    order = np.argsort(fits)
    best = int(order[0])
    score = float(fits[best])
    runner_up = next((j for j in order[1:] if np.isfinite(fits[j])
                      and not _same_pose(mats[best], mats[j], src)), None)
    runner_up = None if runner_up is None else (mats[runner_up], float(fits[runner_up]))
    matrix, iterations, converged, last_step = mats[best], int(iters[best]), bool(conv[best]), step[best]
    # --- polish against the exact closest points on the target's triangles
    if tgt.surface is not None:
        m2, it2, c2, s2, free = _icp(src, tgt, matrix[None], iterations=max_iterations, tolerance=tolerance,
                                     exact=True, check=True, **opts)
        if free[0]:
            raise InfeasibleError(_unconstrained_message(free[0]))
        matrix, iterations = m2[0], iterations + int(it2[0])
        converged, last_step = bool(c2[0]), s2[0]
    if not converged:
        msg = (f"ICP did not converge within {max_iterations} iterations (last step moved points by "
               f"{last_step:.3g} m, tolerance {tolerance:.3g} m); try a closer initial pose (initial=...), "
               "coarse=True, a smaller trim if the clouds overlap only partly, a larger max_iterations, "
               "or a looser tolerance")
        if require_convergence:
            raise InfeasibleError(msg)
        log.warning("registration: %s", msg)
    return _finish(src, tgt, matrix, iterations, converged, trim, inlier_distance, min_inlier_fraction,
                   cos_max, basis, boundary, score, runner_up)


def _subset(src, n, rng):
    """A random subset of about ``n`` source points plus up to ``n`` perimeter points."""
    if len(src.points) <= n:
        return src
    idx = np.sort(rng.choice(len(src.points), size=n, replace=False))
    keep = np.zeros(len(src.points), bool)
    keep[idx] = True
    bmask = np.zeros(len(src.points), bool)
    # keep the perimeter points too (up to n of them): the perimeter fixes a table registration
    perimeter = src.boundary
    if len(perimeter) > n:
        perimeter = rng.choice(perimeter, size=n, replace=False)
    bmask[perimeter] = True
    idx = np.flatnonzero(keep | bmask)
    return _Source(src.points[idx], None if src.normals is None else src.normals[idx], src.weights[idx],
                   src.indices[idx], np.flatnonzero(bmask[idx]))


def _apply(mats, points):
    """Points ``(n, 3)`` under transforms ``(h, 4, 4)`` → ``(h, n, 3)``."""
    return np.einsum("hij,nj->hni", mats[:, :3, :3], points) + mats[:, None, :3, 3]


def _trim_mask(dist, valid, trim):
    """Keep, per row, the ``trim`` fraction of valid correspondences with the smallest distance
    (infinite distances — nothing found within the search bound — are never kept)."""
    d = np.where(valid, dist, np.inf)
    n_valid = valid.sum(axis=1)
    kth = np.clip(np.ceil(trim * n_valid).astype(int) - 1, 0, d.shape[1] - 1)
    cut = np.take_along_axis(np.sort(d, axis=1), kth[:, None], axis=1)
    return valid & np.isfinite(dist) & (dist <= cut)


def _gate(r, kept, size):
    """Of the ``kept`` correspondences ``(a, n)``, drop those whose residual ``r`` ``(a, n)`` lies
    beyond GATE_SIGMAS robust standard deviations (1.4826 × median |r| of the kept ones; at least
    GATE_FLOOR × ``size``).  With outliers close to ``1 - trim`` of the points, the trimmed set
    would otherwise reach into the outliers nearest the surface; and perimeter points without a
    counterpart in the target (a scan that extends beyond the part) would pull the pose."""
    sigma = 1.4826 * _row_median(np.abs(r), kept)
    return kept & (np.abs(r) <= np.maximum(GATE_SIGMAS * sigma, GATE_FLOOR * size)[:, None])


def _row_median(values, mask):
    """Per-row (lower) median ``(a,)`` of ``values`` ``(a, n)`` where ``mask``; inf for empty rows."""
    v = np.sort(np.where(mask, values, np.inf), axis=1)
    m = mask.sum(axis=1)
    return np.where(m > 0, np.take_along_axis(v, np.maximum((m - 1) // 2, 0)[:, None], axis=1)[:, 0], np.inf)


def _icp(src, tgt, starts, *, basis, trim, cos_max, boundary, iterations, tolerance, exact, check,
         bound=None):
    """Trimmed point-to-plane ICP from several start poses at once.

    Each step solves the linearised least squares (Gauss-Newton).  Once a pose has settled its
    trimmed set is frozen (points flipping in and out of the set would otherwise keep it
    jittering) and the steps become Levenberg-Marquardt: a step that raises the objective is
    undone and retried with more damping, so the iteration converges even along motions the
    geometry barely constrains.

    Correspondences are searched within ``bound`` (m; default the source size) at first, then
    within a few times the trimmed distance plus the last step: far points are outliers, and
    bounded nearest-neighbour queries are many times faster.

    Returns the final transforms ``(h, 4, 4)``, the iterations taken ``(h,)``, whether each
    converged ``(h,)``, each last step size ``(h,)`` (m), and ``(h,)`` the motion each pose's
    correspondences left free ("" when constrained; only with ``check``, and such a pose stops)."""
    from scipy.spatial.transform import Rotation

    mats = np.array(starts, dtype=float)
    h, n = len(mats), len(src.points)
    nb = len(src.boundary) if boundary is not None else 0
    iters = np.zeros(h, int)
    conv = np.zeros(h, bool)
    last = np.full(h, np.inf)
    frozen = np.zeros(h, bool)
    keep_fixed = np.zeros((h, n), bool)
    kb_fixed = np.zeros((h, nb), bool)
    settle = SETTLE_STEP * src.size
    # the last accepted pose and its linear system, per start pose
    best = mats.copy()
    best_e = np.full(h, np.inf)
    dim = basis.shape[1]
    sys_a, sys_b = np.zeros((h, dim, dim)), np.zeros((h, dim))
    sys_c, sys_r, sys_ext = np.zeros((h, 3)), np.ones(h), np.zeros(h)
    mu = np.zeros(h)
    free = np.full(h, "", dtype=object)     # the motion a start pose's correspondences leave free
    bounds = np.full(h, src.size if bound is None else float(bound))
    for _ in range(iterations):
        act = np.flatnonzero(~conv)
        if len(act) == 0:
            break
        m = mats[act]
        A, b, e, c, radius, extent, keep, kb, cut, wsum = _system(src, tgt, m, basis, trim, cos_max, boundary,
                                                               exact, frozen[act], keep_fixed[act], kb_fixed[act],
                                                            bounds[act])
        if check:           # a start pose with no or degenerate correspondences is dropped
            bad = _free_motion(A, basis)
            empty = wsum <= 0
            if bad is not None or empty.any():
                drop = empty | (bad[0] if bad is not None else False)
                free[act[drop]] = np.where(empty[drop], NO_MATCH, "" if bad is None else bad[1])
                conv[act[drop]] = True
                keepers = ~drop
                act, m = act[keepers], m[keepers]
                A, b, e, c, radius, extent, keep, kb, cut = (
                    x[keepers] for x in (A, b, e, c, radius, extent, keep, kb, cut))
                if len(act) == 0:
                    break
        worse = frozen[act] & (e > best_e[act])
        good = act[~worse]
        best[good], best_e[good] = m[~worse], e[~worse]
        sys_a[good], sys_b[good], sys_c[good], sys_r[good], sys_ext[good] = (
            A[~worse], b[~worse], c[~worse], radius[~worse], extent[~worse])
        keep_fixed[good], kb_fixed[good] = keep[~worse], kb[~worse]
        mu[good] = np.where(mu[good] > 1e-9, mu[good] / 3.0, 0.0)
        mu[act[worse]] = np.maximum(mu[act[worse]] * 10.0, 1e-4)
        A, b, c, radius = sys_a[act], sys_b[act], sys_c[act], sys_r[act]
        damped = A + mu[act][:, None, None] * (np.eye(dim) * np.diagonal(A, axis1=1, axis2=2)[:, None, :])
        x = np.einsum("aij,aj->ai", np.linalg.pinv(damped, rcond=1e-12, hermitian=True), b)
        delta = np.einsum("ij,aj->ai", basis, x)
        # the linearisation holds for small steps: cap a step at MAX_STEP_ANGLE and one source size
        shrink = np.minimum(1.0, np.minimum(MAX_STEP_ANGLE * radius
                                            / np.maximum(np.linalg.norm(delta[:, :3], axis=1), 1e-300),
                                            src.size / np.maximum(np.linalg.norm(delta[:, 3:], axis=1), 1e-300)))
        delta *= shrink[:, None]
        omega = delta[:, :3] / radius[:, None]
        dt = delta[:, 3:]
        rot = Rotation.from_rotvec(omega).as_matrix()
        step = np.tile(np.eye(4), (len(act), 1, 1))
        step[:, :3, :3] = rot
        step[:, :3, 3] = c + dt - np.einsum("aij,aj->ai", rot, c)
        mats[act] = step @ best[act]
        size = np.linalg.norm(omega, axis=1) * sys_ext[act] + np.linalg.norm(dt, axis=1)
        iters[act] += 1
        last[act] = size
        conv[act] = size < tolerance
        bounds[act] = np.minimum(bounds[act], SEARCH_FACTOR * cut + size + 1e-3 * src.size)
        frozen[act] |= (size < settle) | (iters[act] >= FREEZE_AFTER)
    return mats, iters, conv, last, free


def _system(src, tgt, m, basis, trim, cos_max, boundary, exact, frozen, keep_fixed, kb_fixed, bounds):
    """Correspondences and the linearised least-squares system at poses ``m`` ``(a, 4, 4)``.

    Returns the normal matrices ``(a, d, d)``, right-hand sides ``(a, d)``, objectives ``(a,)``
    (weighted squared residuals, m²), rotation centres ``(a, 3)``, rms radii and largest
    distances from them ``(a,)`` (m), the kept correspondences ``(a, n)``, ``(a, b)``, the
    largest kept distance ``(a,)`` (m) and the total weight kept ``(a,)``."""
    n = len(src.points)
    p = _apply(m, src.points)                                                   # (a, n, 3)
    q, u, d = tgt.match(p.reshape(-1, 3), exact=exact, bound=float(bounds.max()))
    q, u, d = q.reshape(p.shape), u.reshape(p.shape), d.reshape(len(m), n)
    d = np.where(d <= bounds[:, None], d, np.inf)
    # a point with nothing within the bound stays "valid" (an infinitely far correspondence) so
    # that the trimmed fraction is a fraction of all points
    valid = np.ones_like(d, bool)
    if src.normals is not None:
        ns = np.einsum("aij,nj->ani", m[:, :3, :3], src.normals)
        valid &= (np.abs(np.einsum("anj,anj->an", ns, u)) >= cos_max) | ~np.isfinite(d)
    fz = frozen[:, None]
    r = np.einsum("anj,anj->an", p - q, u)
    keep = np.where(fz, keep_fixed & valid & np.isfinite(d), _gate(r, _trim_mask(d, valid, trim), src.size))
    cut = np.max(np.where(keep, d, 0.0), axis=1)
    rows_p, rows_u = [p], [u]
    rows_r = [r]
    rows_w = [np.where(keep, src.weights[None, :], 0.0)]
    kb = kb_fixed
    if boundary is not None and len(src.boundary):
        k, bw = boundary
        pb = p[:, src.boundary]
        if tgt.boundary_tree is not None:
            qb, ub, _ = tgt.match_perimeter(pb.reshape(-1, 3))
            qb, ub = qb.reshape(pb.shape), ub.reshape(pb.shape)
            # the perimeter residual lies in the table plane: trim on its in-plane length
            off = pb - qb
            dpl = np.linalg.norm(off - np.einsum("anj,j->an", off, k)[..., None] * k, axis=2)
            # gate on the in-plane distance, not the residual along the perimeter normal: a point
            # matched far along a straight edge has a small residual but no true counterpart
            kb = np.where(fz, kb_fixed, _gate(dpl, _trim_mask(dpl, np.ones_like(dpl, bool), trim), src.size))
        else:
            qb, ub = q[:, src.boundary], u[:, src.boundary]
            kb = keep[:, src.boundary]
        rows_p.append(pb)
        rows_u.append(ub)
        rows_r.append(np.einsum("anj,anj->an", pb - qb, ub))
        rows_w.append(np.where(kb, bw * src.weights[src.boundary][None, :], 0.0))
    P, U, R, W = (np.concatenate(x, axis=1) for x in (rows_p, rows_u, rows_r, rows_w))
    wsum = W.sum(axis=1)
    wpos = np.maximum(wsum, 1e-300)        # a start pose with nothing nearby stays put
    c = np.einsum("an,anj->aj", W, P) / wpos[:, None]
    off = P - c[:, None]
    dist2 = np.einsum("anj,anj->an", off, off)
    radius = np.maximum(np.sqrt(np.einsum("an,an->a", W, dist2) / wpos), 1e-12)
    extent = np.sqrt(np.max(np.where(W > 0, dist2, 0.0), axis=1))
    J = np.concatenate([np.cross(off, U) / radius[:, None, None], U], axis=2) @ basis      # (a, N, d)
    A = np.einsum("ani,an,anj->aij", J, W, J)
    b = -np.einsum("ani,an,an->ai", J, W, R)
    e = np.einsum("an,an->a", W, R * R)
    return A, b, e, c, radius, extent, keep, kb, cut, wsum


def _free_motion(A, basis):
    """Which normal matrices ``(a, d, d)`` leave a motion free (the geometry slides on itself),
    and the name of the first such motion; None when all are constrained."""
    ev, vec = np.linalg.eigh(A)
    bad = ev[:, 0] <= DEGENERATE_EIGENVALUE * np.maximum(ev[:, -1], 1e-300)
    if not bad.any():
        return None
    motion = basis @ vec[int(np.flatnonzero(bad)[0]), :, 0]
    return bad, _MOTION_NAMES[int(np.argmax(np.abs(motion)))]


def _unconstrained_message(free_motion: str) -> str:
    if free_motion == NO_MATCH:
        return ("no usable correspondences: no source point lies near the target (or every one's normal "
                "disagrees with the target's); check that both are in the same units and give an initial "
                "pose or coarse=True")
    return (f"the registration is unconstrained: the geometry does not fix the {free_motion} (a plane, "
            "sphere, cylinder or other surface that slides on itself); register a part with distinctive "
            "shape, or for a flat part on a table use register_on_table with its perimeter "
            "(boundary_weight > 0)")


def _score(src, tgt, mats, trim, cos_max, boundary, exact):
    """How well each pose ``(h, 4, 4)`` fits, as an RMS distance ``(h,)`` (m): the ``trim``
    fraction of closest source points' distances to the target (to its triangles with ``exact``,
    else to its closest points), plus, on a table, the weighted in-plane distances of the
    perimeter points to the target's perimeter (the trimmed, gated set ICP uses).

    Distances rather than point-to-plane residuals: a pose that hangs the part over the target's
    edge, or slides a flat part within a flat target, keeps small residuals but not small
    distances."""
    h, n = len(mats), len(src.points)
    p = _apply(mats, src.points)
    _, u, d = tgt.match(p.reshape(-1, 3), exact=exact, bound=0.5 * src.size)
    u, d = u.reshape(p.shape), d.reshape(h, n)
    valid = np.ones((h, n), bool)
    if src.normals is not None:
        ns = np.einsum("aij,nj->ani", mats[:, :3, :3], src.normals)
        valid &= (np.abs(np.einsum("anj,anj->an", ns, u)) >= cos_max) | ~np.isfinite(d)
    # the n_trim closest (an incompatible normal counts as far away)
    n_trim = max(int(np.ceil(trim * n)), 1)
    d = np.sort(np.where(valid, d, np.inf), axis=1)[:, :n_trim]
    num, den = np.sum(d * d, axis=1), np.full(h, float(n_trim))
    if boundary is not None and len(src.boundary) and tgt.boundary_tree is not None:
        k, bw = boundary
        pb = p[:, src.boundary]
        qb, _, _ = tgt.match_perimeter(pb.reshape(-1, 3))
        off = pb - qb.reshape(pb.shape)
        dpl = np.linalg.norm(off - np.einsum("anj,j->an", off, k)[..., None] * k, axis=2)
        kb = _gate(dpl, _trim_mask(dpl, np.ones_like(dpl, bool), trim), src.size)
        wb = np.where(kb, bw, 0.0)
        num, den = num + np.einsum("an,an->a", wb, np.where(kb, dpl, 0.0) ** 2), den + wb.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(num / den)


def _centroid_shift(a, b, src):
    """Distance (m) between where poses ``a`` and ``b`` put the source centroid."""
    return float(np.linalg.norm((a[:3, :3] - b[:3, :3]) @ src.centroid + a[:3, 3] - b[:3, 3]))


def _same_pose(a, b, src):
    return (rotation_angle(a[:3, :3].T @ b[:3, :3]) < SAME_POSE_ANGLE
            and _centroid_shift(a, b, src) < SAME_POSE_SHIFT * src.size)


def _distinct(mats, order, src, keep):
    """Indices of the first ``keep`` poses in ``order`` that differ from each other."""
    chosen = []
    for i in order:
        if all(not _same_pose(mats[i], mats[j], src) for j in chosen):
            chosen.append(int(i))
        if len(chosen) == keep:
            break
    return np.array(chosen)


def _residuals(src, tgt, matrix, cos_max):
    """Signed point-to-plane residuals ``(n,)``, distances ``(n,)`` (m) to the exact closest target
    points, and which correspondences have compatible normals ``(n,)``.  Points with no target
    point within FAR_FRACTION of the source size get residual NaN and distance inf."""
    p = _apply(matrix[None], src.points)[0]
    q, u, d = tgt.match(p, exact=True, bound=FAR_FRACTION * src.size)
    r = np.where(np.isfinite(d), np.einsum("nj,nj->n", p - q, u), np.nan)
    valid = np.ones(len(p), bool)
    if src.normals is not None:
        valid &= np.abs(np.einsum("nj,nj->n", src.normals @ matrix[:3, :3].T, u)) >= cos_max
    return r, d, valid


def _inlier_rms(src, r, inl):
    return float(np.sqrt(np.average(r[inl] ** 2, weights=src.weights[inl]))) if inl.any() else float("inf")


def _uncertainty(src, tgt, matrix, basis, trim, cos_max, boundary):
    """One-sigma uncertainty of the rotation (rad) and of the translation at the source centroid
    (m), from the least-squares covariance ``σ² (JᵀWJ)⁻¹`` at the final pose (σ² the weighted
    mean squared residual), and the least-determined motion as a unit 6-vector
    ``(rotation axis × rms radius, translation)``.  Treats residuals as independent: where they are
    correlated (a CAD that differs in shape from the scan) the true uncertainty is larger."""
    A, _, e, _, radius, _, _, _, _, wsum = _system(
        src, tgt, matrix[None], basis, trim, cos_max, boundary, True, np.zeros(1, bool),
        np.zeros((1, len(src.points)), bool), np.zeros((1, len(src.boundary) if boundary else 0), bool),
        np.array([np.inf]))
    cov_b = (e[0] / max(wsum[0], 1e-300)) * np.linalg.pinv(A[0], rcond=1e-15, hermitian=True)
    cov = basis @ cov_b @ basis.T                                 # of (ω · radius, δt)
    rot = float(np.sqrt(np.linalg.eigvalsh(cov[:3, :3])[-1])) / radius[0]
    tra = float(np.sqrt(np.linalg.eigvalsh(cov[3:, 3:])[-1]))
    ev, vec = np.linalg.eigh(cov)
    return rot, tra, vec[:, -1] * np.sign(vec[np.argmax(np.abs(vec[:, -1])), -1])


def _describe_motion(motion, centroid):
    """Words for a unit 6-vector ``(rotation × radius, translation)``."""
    w, t = motion[:3], motion[3:]
    if np.linalg.norm(w) >= np.linalg.norm(t):
        return (f"rotation about axis {np.round(w / np.linalg.norm(w), 2).tolist()} through "
                f"{np.round(centroid, 3).tolist()} m")
    return f"translation along {np.round(t / np.linalg.norm(t), 2).tolist()}"


def _finish(src, tgt, matrix, iterations, converged, trim, inlier_distance, min_inlier_fraction, cos_max,
            basis, boundary, score, runner_up):
    r, d, valid = _residuals(src, tgt, matrix, cos_max)
    if inlier_distance is None:
        kept = _trim_mask(d[None], valid[None], trim)[0]
        sigma = 1.4826 * np.median(np.abs(r[kept])) if kept.any() else np.inf
        inlier_distance = float(np.clip(3 * sigma, 1e-3 * src.size, 1e-2 * src.size))
    # without triangles the closest vertex may be up to about a point spacing away sideways: a
    # point-cloud target judges inliers by the distance to the tangent plane
    reach = inlier_distance + (0.0 if tgt.surface is not None else 2.0 * tgt.spacing)
    inl = valid & (np.abs(np.nan_to_num(r, nan=np.inf)) <= inlier_distance) & (d <= reach)
    frac = float(inl.mean())
    rms = _inlier_rms(src, r, inl)
    if frac < min_inlier_fraction:
        raise InfeasibleError(
            f"only {100 * frac:.1f}% of the source points lie within {1e3 * inlier_distance:.3g} mm of the "
            f"target after registration (need {100 * min_inlier_fraction:.0f}%): the two do not overlap, or "
            "the global alignment failed; check that both are the same part in the same units, give an "
            "initial pose, or lower min_inlier_fraction for a partial scan")
    runner_score = runner_angle = runner_shift = None
    if runner_up is not None:
        other, runner_score = runner_up
        runner_angle = rotation_angle(matrix[:3, :3].T @ other[:3, :3])
        runner_shift = _centroid_shift(matrix, other, src)
    sig_rot, sig_tra, weakest = _uncertainty(src, tgt, matrix, basis, trim, cos_max, boundary)
    centroid = matrix[:3, :3] @ src.centroid + matrix[:3, 3]
    weak_text = _describe_motion(weakest, centroid)
    result = Registration(matrix=_ro(matrix.copy()), rms=rms, inlier_fraction=frac,
                          inlier_distance=float(inlier_distance), iterations=iterations, converged=converged,
                          point_indices=_ro(src.indices.copy()), residuals=_ro(r), inliers=_ro(inl),
                          dof=basis.shape[1], score=score, runner_up_score=runner_score,
                          runner_up_angle=runner_angle, runner_up_shift=runner_shift,
                          source_centroid=_ro(src.centroid.copy()), sigma_rotation=sig_rot,
                          sigma_translation=sig_tra, weakest_motion=weak_text)
    log.info("registration: rms %.4g mm over %.1f%% inliers, %d iterations, rotation %.3f deg; "
             "1-sigma %.3g mm / %.3g deg", 1e3 * rms, 100 * frac, iterations, np.degrees(result.angle),
             1e3 * sig_tra, np.degrees(sig_rot))
    warnings = quality_warnings(frac, rms, inlier_distance, src.size, score, runner_score, runner_angle,
                                runner_shift, sig_tra, sig_rot, weak_text)
    for w in warnings:
        log.warning("registration: %s", w)
    result = replace(result, warnings=tuple(warnings))
    return result


def quality_warnings(inlier_fraction, rms, inlier_distance, size, score, runner_up_score, runner_up_angle, runner_up_shift,
                     sigma_translation, sigma_rotation, weakest_motion) -> list[str]:
    """What makes a registration poor or ambiguous, in words (empty when nothing does).

    Poor: fewer than :data:`POOR_INLIERS` of the source points are inliers, or the inlier rms is
    above :data:`POOR_RMS` of the source size (``size``, m).  Ambiguous: the best distinct pose
    scores within :data:`AMBIGUOUS_SCORE` of the chosen one, or the one-sigma uncertainty at the
    part's edge exceeds the inlier distance.  Lengths in m, angles in rad.
    """
    out = []
    if inlier_fraction < POOR_INLIERS:
        out.append(f"only {100 * inlier_fraction:.1f} % of the CAD points lie within {1e3 * inlier_distance:.3g} mm of "
                   f"the scan (below {100 * POOR_INLIERS:.0f} %): the scan covers part of the CAD, or the two differ "
                   "in shape; check the residuals (residuals.csv) before trusting the pose")
    if rms > POOR_RMS * size:
        out.append(f"the inlier rms {1e3 * rms:.3g} mm is {100 * rms / size:.2f} % of the part's size (above "
                   f"{100 * POOR_RMS:.1f} %): the CAD and the scan differ in shape by about that much, so the pose is "
                   "a compromise between them")
    if runner_up_score is not None and runner_up_score < AMBIGUOUS_SCORE * score:
        out.append(f"ambiguous: another pose (turned {np.degrees(runner_up_angle):.1f} deg, centroid "
                   f"{1e3 * runner_up_shift:.3g} mm away) fits within {100 * (runner_up_score / score - 1):.0f} % of the "
                   f"best (score {1e3 * runner_up_score:.4g} vs {1e3 * score:.4g} mm; within "
                   f"{100 * (AMBIGUOUS_SCORE - 1):.0f} % counts as ambiguous); give an initial pose to pick one, or "
                   "register on the table with the perimeter")
    if sigma_translation + sigma_rotation * size / 2 > inlier_distance:
        out.append(f"the pose is poorly determined (1-sigma {1e3 * sigma_translation:.3g} mm at the centroid, "
                   f"{np.degrees(sigma_rotation):.3g} deg): the surface nearly slides on itself by {weakest_motion}; "
                   "register on the table with the perimeter, or check the pose against features")
    return out


def _ro(a):
    a.setflags(write=False)
    return a
