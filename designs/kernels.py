"""Compiled kernels of the design search (numba, cached beside the sources): model rows, the
disallowed-combination programs, one start of the coordinate exchange (`optimise_start`) and its
iterated local search on the grid (`iterate_start`).

The exchange keeps V = (X'X)^-1 and judges replacing a run's row x by a trial row y from
y'Vy, x'Vy, x'Vx and, for the trace criteria, a'Wa and a'Wb (a = Vy, b = Vx). A trial that moves
one coordinate changes only the model columns of that factor: D needs only y'Vy and x'Vy, which
follow from the change of those columns alone (`_trial_d`, about c^2 for c changed columns), and
the trace criteria get a = Vy for p per changed column from the row it leaves (`_trial_near`); a
whole candidate point costs O(p^2).

- D: det rises by the factor (1 - x'Vx)(1 + y'Vy) + (x'Vy)^2 (Fedorov's delta)
- I and A: trace(W V) falls by the Woodbury identity with the 2 x 2 core of the exchange, W the
  region's moment matrix (I) or the identity (A)

A move taken updates V by the same rank-two Woodbury step; V is recomputed from X once a pass.
A continuous coordinate enters each model column as a polynomial of degree at most 3, so those
quantities are polynomials of degree at most 6 in it: seven probes fix them exactly, and the
best value is found on a fine grid, then refined around its best point.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from designs.constraints import ADD, AND, CATEGORICAL, CONST, DIV, EQ, GE, GT, LE, LT, MUL, NE, NEG, NOT, SUB, VAR
from designs.exchange_numerics import CORE_LOST, GAIN_TOLERANCE, RIDGE, SINGULAR_CONDITION

#: Compiled once and cached; the GIL is released, so starts can search on threads side by side.
kernel = njit(cache=True, nogil=True)

#: Points of the fine grid a continuous coordinate is first searched on, and its refinements.
_FINE_POINTS = 201
_ZOOM_POINTS = 21
_ZOOMS = 5


@kernel
def model_columns(s, kinds, levels, col_factor, col_code, cols, count, out):
    """Model columns `cols[:count]` of one point `s` (coded settings; level indices for categorical factors)
    into the same places of `out`; every column when `cols` is None (numba compiles that case apart)."""
    for t in range(count):
        c = t if cols is None else cols[t]
        value = 1.0
        for q in range(col_factor.shape[1]):
            f = col_factor[c, q]
            if f < 0:
                break
            x = s[f]
            if kinds[f] == CATEGORICAL:
                level = int(x)
                if level == levels[f] - 1:
                    value = -value
                elif level != col_code[c, q]:
                    value = 0.0
            else:
                for _ in range(col_code[c, q]):
                    value *= x
        out[c] = value


@kernel
def model_row(s, kinds, levels, col_factor, col_code, out):
    """The model row of one point `s` into `out`."""
    model_columns(s, kinds, levels, col_factor, col_code, None, col_factor.shape[0], out)


@kernel
def _close(a, b):
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


@kernel
def disallowed(s, centre, half, kinds, ops, args, bounds, stack):
    """Whether point `s` satisfies any of the programs (program e is ops[bounds[e]:bounds[e + 1]]).

    Numeric factors are read in their own units, categorical ones as level indices.
    """
    for e in range(len(bounds) - 1):
        top = 0
        for i in range(bounds[e], bounds[e + 1]):
            op = ops[i]
            if op == VAR:
                f = int(args[i])
                stack[top] = s[f] if kinds[f] == CATEGORICAL else centre[f] + half[f] * s[f]
                top += 1
            elif op == CONST:
                stack[top] = args[i]
                top += 1
            elif op == NEG:
                stack[top - 1] = -stack[top - 1]
            elif op == NOT:
                stack[top - 1] = 1.0 if stack[top - 1] == 0.0 else 0.0
            else:
                b = stack[top - 1]
                a = stack[top - 2]
                top -= 1
                if op == ADD:
                    r = a + b
                elif op == SUB:
                    r = a - b
                elif op == MUL:
                    r = a * b
                elif op == DIV:
                    r = a / b if b != 0.0 else np.nan
                elif op == LT:
                    r = 1.0 if a < b and not _close(a, b) else 0.0
                elif op == LE:
                    r = 1.0 if a < b or _close(a, b) else 0.0
                elif op == GT:
                    r = 1.0 if a > b and not _close(a, b) else 0.0
                elif op == GE:
                    r = 1.0 if a > b or _close(a, b) else 0.0
                elif op == EQ:
                    r = 1.0 if _close(a, b) else 0.0
                elif op == NE:
                    r = 0.0 if _close(a, b) else 1.0
                elif op == AND:
                    r = 1.0 if a != 0.0 and b != 0.0 else 0.0
                else:
                    r = 1.0 if a != 0.0 or b != 0.0 else 0.0
                stack[top - 1] = r
        if stack[0] != 0.0:
            return True
    return False


@kernel
def _mat_vec(matrix, vector, out):
    n = len(vector)
    for a in range(n):
        total = 0.0
        for b in range(n):
            total += matrix[a, b] * vector[b]
        out[a] = total


@kernel
def _dot(a, b):
    total = 0.0
    for j in range(len(a)):
        total += a[j] * b[j]
    return total


@kernel
def _scores(y, a, b, wb, weight, trace, wa, out):
    """Into `out`: y'Vy, x'Vy, a'Wa and a'Wb for trial row y, given a = Vy and b = Vx (x the run's present row)."""
    out[0] = _dot(y, a)
    out[1] = _dot(b, y)
    if trace:
        _mat_vec(weight, a, wa)
        out[2] = _dot(a, wa)
        out[3] = _dot(a, wb)


@kernel
def _trial(y, inv, b, wb, weight, trace, a, wa, out):
    """`_scores` of trial row y, with a = Vy computed in full (p^2)."""
    _mat_vec(inv, y, a)
    _scores(y, a, b, wb, weight, trace, wa, out)


@kernel
def _trial_near(y, base, a_base, cols, count, inv, b, wb, weight, trace, a, wa, out):
    """`_trial` for a row y that differs from `base` (with a_base = V base) only in the columns `cols[:count]`:
    a = Vy costs p per changed column instead of p^2."""
    p = len(y)
    for r in range(p):
        a[r] = a_base[r]
    for t in range(count):
        c = cols[t]
        change = y[c] - base[c]
        if change != 0.0:
            for r in range(p):
                a[r] += inv[c, r] * change  # V is symmetric: row c is column c, read in memory order
    _scores(y, a, b, wb, weight, trace, wa, out)


@kernel
def _trial_d(y, base, a_base, d_base, xb, b, inv, cols, count, delta, out):
    """y'Vy and x'Vy into out[0] and out[1] for a trial row y that differs from `base` only in the
    columns `cols[:count]` (a = V base, d_base = base'V base, xb = x'V base): with delta = y - base on those
    columns, y'Vy = d_base + 2 delta'a + delta'V delta and x'Vy = xb + delta'b, about count^2 + 2 count flops
    instead of the p^2 / p x count of forming Vy. The D criterion needs nothing else."""
    for t in range(count):
        delta[t] = y[cols[t]] - base[cols[t]]
    dy = d_base
    dxy = xb
    for t in range(count):
        change = delta[t]
        if change != 0.0:
            c = cols[t]
            quad = 0.0
            for u in range(count):
                quad += inv[c, cols[u]] * delta[u]
            dy += change * (2.0 * a_base[c] + quad)
            dxy += change * b[c]
    out[0] = dy
    out[1] = dxy


@kernel
def factor_columns(col_factor, k):
    """(k, p) the model columns each factor enters, and (k,) how many: a move of factor f changes only those."""
    p, parts = col_factor.shape
    cols = np.zeros((k, p), dtype=np.int64)
    count = np.zeros(k, dtype=np.int64)
    for c in range(p):
        for q in range(parts):
            f = col_factor[c, q]
            if f >= 0 and (count[f] == 0 or cols[f, count[f] - 1] != c):
                cols[f, count[f]] = c
                count[f] += 1
    return cols, count


@kernel
def _gain(dy, dxy, awa, awb, dx, bwb, trace):
    """What replacing the row x by y gains (larger is better; 0 for y = x).

    D: log of det(M')/det(M) = (1 - x'Vx)(1 + y'Vy) + (x'Vy)^2 (Fedorov's delta). I and A: the fall
    of trace(W V), from the Woodbury identity with the 2 x 2 core S = [[1 + y'Vy, x'Vy], [x'Vy, x'Vx - 1]],
    whose determinant is minus that ratio.
    """
    ratio = (1.0 - dx) * (1.0 + dy) + dxy * dxy
    if ratio <= 1e-12:
        return -np.inf
    if trace:
        return -((dx - 1.0) * awa - 2.0 * dxy * awb + (1.0 + dy) * bwb) / ratio
    return np.log(ratio)


@kernel
def _poly(coefficients, t):
    total = 0.0
    for j in range(len(coefficients) - 1, -1, -1):
        total = total * t + coefficients[j]
    return total


@kernel
def _checked_inverse(info):
    """(False, (X'X)^-1), or (True, X'X) when X'X is singular to working precision. Its condition number decides, not
    its determinant: X'X of a singular design with integer codes comes out of the factorization with a tiny positive
    determinant, whose inverse is then all rounding error (a saturated plan's random start, say). The bound
    cond(X'X) <= |X'X|_F |(X'X)^-1|_F settles most designs without the SVD the condition number takes, the costliest
    step of a pass otherwise."""
    sign, _ = np.linalg.slogdet(info)
    if sign <= 0:
        return True, info
    inv = np.linalg.inv(info)
    if np.sqrt(np.sum(info * info) * np.sum(inv * inv)) <= SINGULAR_CONDITION or np.linalg.cond(info) <= SINGULAR_CONDITION:
        return False, inv
    return True, info


@kernel
def _inverse(x):
    """V = (X'X)^-1 of the model rows `x`, with a small ridge on the diagonal when X'X is singular, so the
    exchange can still move a singular start towards a design that estimates every term."""
    info = x.T @ x
    singular, inv = _checked_inverse(info)
    if not singular:
        return inv
    ridge = RIDGE * max(1.0, np.trace(info) / info.shape[0])
    for r in range(info.shape[0]):
        info[r, r] += ridge
    return np.linalg.inv(info)


@kernel
def _exchange_row(inv, x_old, y, b, a):
    """V = (X'X)^-1 in place after the row x_old is replaced by y (rank-two Woodbury update); False, V untouched,
    when the update's 2 x 2 core is singular to working precision (its determinant lost in rounding), so the
    caller inverts X'X afresh instead."""
    _mat_vec(inv, y, a)
    _mat_vec(inv, x_old, b)
    dy = _dot(y, a)
    dx = _dot(x_old, b)
    dxy = _dot(b, y)
    det = (1.0 + dy) * (dx - 1.0) - dxy * dxy
    if abs(det) <= CORE_LOST * max(abs((1.0 + dy) * (dx - 1.0)), dxy * dxy, 1.0):
        return False
    s11 = (dx - 1.0) / det
    s12 = -dxy / det
    s22 = (1.0 + dy) / det
    p = len(y)
    for r in range(p):
        for c in range(p):
            inv[r, c] -= s11 * a[r] * a[c] + s12 * (a[r] * b[c] + b[r] * a[c]) + s22 * b[r] * b[c]
    return True


@kernel
def optimise_start(settings, kinds, levels, col_factor, col_code, centre, half, values, value_count,
                   continuous, frozen, weight, trace, ops, args, bounds, cand_settings, probes, probe_inverse,
                   max_passes, first_free):
    """Coordinate exchange of one start, in place on `settings`; returns the passes made.

    Rows before `first_free` are kept as they are (the runs of a study being augmented), and so are
    the coordinates of `frozen` factors (a run's block or covariate).

    `values[f, :value_count[f]]` are the settings factor f may take when it is not continuous;
    `cand_settings` are whole points tried as row swaps (none: an empty array).
    """
    n, k = settings.shape
    p = col_factor.shape[0]
    x = np.empty((n, p))
    for i in range(n):
        model_row(settings[i], kinds, levels, col_factor, col_code, x[i])
    y = np.empty(p)
    a = np.empty(p)
    wa = np.empty(p)
    b = np.empty(p)
    wb = np.empty(p)
    x_old = np.empty(p)
    base = np.empty(p)
    a_base = np.empty(p)
    cols, col_count = factor_columns(col_factor, k)
    delta = np.empty(p)
    out = np.zeros(4)
    stack = np.empty(max(len(ops), 1))
    trial = np.empty(k)
    best_point = np.empty(k)
    n_probes = len(probes)
    sampled = np.zeros((4, n_probes))
    fitted = np.zeros((4, n_probes))
    fine = np.linspace(-1.0, 1.0, _FINE_POINTS)
    constrained = len(bounds) > 1
    passes = 0
    for _ in range(max_passes):
        passes += 1
        inv = _inverse(x)
        tolerance = GAIN_TOLERANCE
        if trace:
            tolerance = GAIN_TOLERANCE * max(np.sum(weight * inv), 1e-300)
        improved = False
        for i in range(first_free, n):
            _mat_vec(inv, x[i], b)
            dx = _dot(x[i], b)
            bwb = 0.0
            if trace:
                _mat_vec(weight, b, wb)
                bwb = _dot(b, wb)
            best = 0.0
            for j in range(k):
                best_point[j] = settings[i, j]
            for r in range(p):
                base[r] = x[i, r]
                a_base[r] = b[r]
            d_base = dx
            xb = dx
            moved = False  # best_point has left the run's row: base and a_base must follow it
            for f in range(k):
                if frozen[f]:
                    continue
                if moved:
                    model_row(best_point, kinds, levels, col_factor, col_code, base)
                    _mat_vec(inv, base, a_base)
                    d_base = _dot(base, a_base)
                    xb = _dot(b, base)
                    moved = False
                for j in range(k):
                    trial[j] = best_point[j]
                if continuous[f]:
                    for r in range(n_probes):
                        trial[f] = probes[r]
                        # Written out here and below: one compiled function around these two branches, taking all
                        # their arrays, made a grid pass 2.4 times slower (numba does not inline it).
                        if trace:
                            model_row(trial, kinds, levels, col_factor, col_code, y)
                            _trial_near(y, base, a_base, cols[f], col_count[f], inv, b, wb, weight, trace, a, wa, out)
                        else:
                            model_columns(trial, kinds, levels, col_factor, col_code, cols[f], col_count[f], y)
                            _trial_d(y, base, a_base, d_base, xb, b, inv, cols[f], col_count[f], delta, out)
                        for m in range(4):
                            sampled[m, r] = out[m]
                    for m in range(4):
                        for r in range(n_probes):
                            total = 0.0
                            for c in range(n_probes):
                                total += probe_inverse[r, c] * sampled[m, c]
                            fitted[m, r] = total
                    chosen = best_point[f]
                    top = best
                    limit = np.exp(top + tolerance)  # D: the determinant ratio a point must pass, so few take a log
                    centre_t = 0.0
                    step = fine[1] - fine[0]
                    for zoom in range(_ZOOMS + 1):
                        count = _FINE_POINTS if zoom == 0 else _ZOOM_POINTS
                        for r in range(count):
                            t = fine[r] if zoom == 0 else centre_t + step * (r - (_ZOOM_POINTS - 1) / 2) / ((_ZOOM_POINTS - 1) / 2)
                            if t < -1.0 or t > 1.0:
                                continue
                            dy = _poly(fitted[0], t)
                            dxy = _poly(fitted[1], t)
                            if trace:
                                g = _gain(dy, dxy, _poly(fitted[2], t), _poly(fitted[3], t), dx, bwb, trace)
                            elif (1.0 - dx) * (1.0 + dy) + dxy * dxy > limit:
                                g = _gain(dy, dxy, 0.0, 0.0, dx, bwb, trace)
                            else:
                                continue
                            if g > top + tolerance:
                                if constrained:
                                    trial[f] = t
                                    if disallowed(trial, centre, half, kinds, ops, args, bounds, stack):
                                        continue
                                top = g
                                limit = np.exp(top + tolerance)
                                chosen = t
                        centre_t = chosen
                        step = step / ((_ZOOM_POINTS - 1) / 2)
                    if top > best + tolerance:
                        best = top
                        best_point[f] = chosen
                        moved = True
                else:
                    for r in range(value_count[f]):
                        value = values[f, r]
                        if value == best_point[f]:
                            continue
                        trial[f] = value
                        if constrained and disallowed(trial, centre, half, kinds, ops, args, bounds, stack):
                            continue
                        if trace:
                            model_row(trial, kinds, levels, col_factor, col_code, y)
                            _trial_near(y, base, a_base, cols[f], col_count[f], inv, b, wb, weight, trace, a, wa, out)
                        else:
                            model_columns(trial, kinds, levels, col_factor, col_code, cols[f], col_count[f], y)
                            _trial_d(y, base, a_base, d_base, xb, b, inv, cols[f], col_count[f], delta, out)
                        g = _gain(out[0], out[1], out[2], out[3], dx, bwb, trace)
                        if g > best + tolerance:
                            best = g
                            best_point[f] = value
                            moved = True
            for c in range(len(cand_settings)):
                for j in range(k):
                    trial[j] = best_point[j] if frozen[j] else cand_settings[c, j]
                if constrained and disallowed(trial, centre, half, kinds, ops, args, bounds, stack):
                    continue
                model_row(trial, kinds, levels, col_factor, col_code, y)
                _trial(y, inv, b, wb, weight, trace, a, wa, out)
                g = _gain(out[0], out[1], out[2], out[3], dx, bwb, trace)
                if g > best + tolerance:
                    best = g
                    for j in range(k):
                        best_point[j] = trial[j]
            if best > tolerance:
                improved = True
                for j in range(k):
                    settings[i, j] = best_point[j]
                for r in range(p):
                    x_old[r] = x[i, r]
                model_row(settings[i], kinds, levels, col_factor, col_code, x[i])
                if not _exchange_row(inv, x_old, x[i], b, a):
                    inv = _inverse(x)
        if not improved:
            break
    return passes


@kernel
def criterion_of(settings, kinds, levels, col_factor, col_code, weight, trace):
    """The design's criterion as a gain (larger is better): log det(X'X) for D, -trace(W (X'X)^-1) for I and A;
    -inf when X'X is singular."""
    n = settings.shape[0]
    p = col_factor.shape[0]
    x = np.empty((n, p))
    for i in range(n):
        model_row(settings[i], kinds, levels, col_factor, col_code, x[i])
    info = x.T @ x
    singular, inv = _checked_inverse(info)
    if singular:
        return -np.inf
    if trace:
        return -np.sum(weight * inv)
    return np.linalg.slogdet(info)[1]


@kernel
def iterate_start(settings, kinds, levels, col_factor, col_code, centre, half, values, value_count,
                  frozen, weight, trace, ops, args, bounds, probes, probe_inverse, max_passes, first_free,
                  candidates, kick_rows, kick_points, patience):
    """Iterated local search on the grid, in place on `settings`; returns the kicks made.

    Kick j replaces the runs `kick_rows[j]` by the candidate points `kick_points[j]` (a run keeps its
    frozen coordinates, and a kicked run that lands on a disallowed point stays as it was), runs the
    coordinate exchange on the grid again and keeps the result when the criterion is no worse. A few
    runs moved at once leave the local optimum that single-coordinate moves cannot. The search stops
    early once `patience` kicks in a row have not raised the criterion: it is then held in an optimum
    that a few kicks cannot leave, and the work left is better spent from a fresh opening.
    """
    n, k = settings.shape
    grid_only = np.zeros(k, dtype=np.bool_)
    no_swaps = np.zeros((0, k))
    stack = np.empty(max(len(ops), 1))
    constrained = len(bounds) > 1
    current = criterion_of(settings, kinds, levels, col_factor, col_code, weight, trace)
    trial = np.empty_like(settings)
    still = 0
    for j in range(kick_rows.shape[0]):
        trial[:, :] = settings
        for r in range(kick_rows.shape[1]):
            row = kick_rows[j, r]
            point = trial[row].copy()
            for f in range(k):
                if not frozen[f]:
                    point[f] = candidates[kick_points[j, r], f]
            if not (constrained and disallowed(point, centre, half, kinds, ops, args, bounds, stack)):
                trial[row] = point
        optimise_start(trial, kinds, levels, col_factor, col_code, centre, half, values, value_count, grid_only, frozen,
                       weight, trace, ops, args, bounds, no_swaps, probes, probe_inverse, max_passes, first_free)
        value = criterion_of(trial, kinds, levels, col_factor, col_code, weight, trace)
        still += 1
        if value >= current:
            if value > current + 1e-9 * max(1.0, abs(current)):
                still = 0
            settings[:, :] = trial
            current = value
        if still >= patience:
            return j + 1
    return kick_rows.shape[0]
