"""The Mamdani fuzzy system of [D]'s self-tuning PID (eq. 10, Table 2): E, EC → ΔKp, ΔKi, ΔKd.

Section 2 of ``docs/reference-controllers.md``, exactly:

* inputs E, EC on [-6, 6]: seven triangles NB … PB, peaks -6, -4, … 6, half-width 2;
* outputs on [-3, 3]: seven triangles, peaks -3 … 3, half-width 1;
* rule weight = min(μ_E, μ_EC); each rule clips its output set at its weight; aggregation by
  max; centroid on the 61-point grid x_j = -3 + 0.1·j (0 if Σμ = 0);
* the rule tables are the classic fuzzy-PID tables (Liu Jinkun, *Advanced PID Control*);
  [D] does not publish its own.

Speed (it runs 100 times per simulated second, in pure Python): only the (at most two) sets of
each input with μ > 0 fire, so at most four rules; rules that land on the same output set are
merged first (max of their weights: min(w, μ) is monotone in w), and each output set's
membership on the grid is a precomputed list over its support only.

>>> up, ui, ud = fuzzy_gains(0.0, 0.0)   # E = EC = 0: only rule ZE x ZE fires
>>> round(up, 12), round(ui, 12), round(ud, 12)   # ΔKp, ΔKi: ZE; ΔKd: NS (the table)
(0.0, 0.0, -1.0)
"""

from __future__ import annotations

NB, NM, NS, ZE, PS, PM, PB = range(7)
LABELS = ("NB", "NM", "NS", "ZE", "PS", "PM", "PB")

INPUT_LIMIT = 6.0
INPUT_HALF_WIDTH = 2.0
OUTPUT_LIMIT = 3.0
GRID = tuple(-3.0 + 0.1 * j for j in range(61))
"""The centroid grid x_j = -3 + 0.1·j, j = 0 … 60."""

# Rows e = NB … PB, columns ec = NB … PB (the contract's tables, cell by cell).
DELTA_KP: tuple[tuple[int, ...], ...] = (
    (PB, PB, PM, PM, PS, ZE, ZE),
    (PB, PB, PM, PS, PS, ZE, NS),
    (PM, PM, PM, PS, ZE, NS, NS),
    (PM, PM, PS, ZE, NS, NM, NM),
    (PS, PS, ZE, NS, NS, NM, NM),
    (PS, ZE, NS, NM, NM, NM, NB),
    (ZE, ZE, NM, NM, NM, NB, NB),
)
DELTA_KI: tuple[tuple[int, ...], ...] = (
    (NB, NB, NM, NM, NS, ZE, ZE),
    (NB, NB, NM, NS, NS, ZE, ZE),
    (NB, NM, NS, NS, ZE, PS, PS),
    (NM, NM, NS, ZE, PS, PM, PM),
    (NM, NS, ZE, PS, PS, PM, PB),
    (ZE, ZE, PS, PS, PM, PB, PB),
    (ZE, ZE, PS, PM, PM, PB, PB),
)
DELTA_KD: tuple[tuple[int, ...], ...] = (
    (PS, NS, NB, NB, NB, NM, PS),
    (PS, NS, NB, NM, NM, NS, ZE),
    (ZE, NS, NM, NM, NS, NS, ZE),
    (ZE, NS, NS, NS, NS, NS, ZE),
    (ZE, ZE, ZE, ZE, ZE, ZE, ZE),
    (PB, NS, PS, PS, PS, PS, PB),
    (PB, PM, PM, PM, PS, PS, PB),
)
TABLES = (DELTA_KP, DELTA_KI, DELTA_KD)


def triangle(x: float, peak: float, half_width: float) -> float:
    """Triangular membership ``max(0, 1 - |x - peak| / half_width)``."""
    d = abs(x - peak) / half_width
    return 1.0 - d if d < 1.0 else 0.0


def input_membership(x: float, label: int) -> float:
    """μ of set ``label`` (0 = NB … 6 = PB) for an input, clamped to [-6, 6] first."""
    x = min(max(x, -INPUT_LIMIT), INPUT_LIMIT)
    return triangle(x, -INPUT_LIMIT + INPUT_HALF_WIDTH * label, INPUT_HALF_WIDTH)


def output_membership(x: float, label: int) -> float:
    """μ of output set ``label`` (peaks -3 … 3, half-width 1)."""
    return triangle(x, -OUTPUT_LIMIT + label, 1.0)


def active_sets(x: float) -> list[tuple[int, float]]:
    """The input sets with μ > 0 at ``x`` (clamped to [-6, 6]) as (label, μ): one or two.

    Same numbers as :func:`input_membership` (μ = 1 - |x - peak| / 2), found without looping
    over the seven sets.
    """
    x = min(max(x, -INPUT_LIMIT), INPUT_LIMIT)
    i = int((x + INPUT_LIMIT) // INPUT_HALF_WIDTH)
    if i >= 6:
        return [(6, 1.0)]
    lo = triangle(x, -INPUT_LIMIT + INPUT_HALF_WIDTH * i, INPUT_HALF_WIDTH)
    hi = triangle(x, -INPUT_LIMIT + INPUT_HALF_WIDTH * (i + 1), INPUT_HALF_WIDTH)
    out = []
    if lo > 0.0:
        out.append((i, lo))
    if hi > 0.0:
        out.append((i + 1, hi))
    return out


def _support(label: int) -> tuple[tuple[int, float], ...]:
    """(grid index, μ) of output set ``label`` where μ > 0."""
    out = []
    for j, x in enumerate(GRID):
        mu = output_membership(x, label)
        if mu > 0.0:
            out.append((j, mu))
    return tuple(out)


SUPPORT: tuple[tuple[tuple[int, float], ...], ...] = tuple(_support(k) for k in range(7))
if any([j for j, _ in sup] != list(range(sup[0][0], sup[-1][0] + 1)) for sup in SUPPORT):
    raise AssertionError("fuzzy: an output set's support is not contiguous on the grid")
_FIRST = tuple(sup[0][0] for sup in SUPPORT)
_END = tuple(sup[-1][0] + 1 for sup in SUPPORT)
#: (ΔKp, ΔKi, ΔKd) output labels of rule (e, ec)
RULES = tuple(tuple((DELTA_KP[i][k], DELTA_KI[i][k], DELTA_KD[i][k]) for k in range(7))
              for i in range(7))


#: per output set: its μ over its support, ascending (the values of SUPPORT)
_MU = tuple(tuple(m for _, m in sup) for sup in SUPPORT)


def centroid(weights: dict[int, float]) -> float:
    """Defuzzify: output sets clipped at their weights, max-aggregated, centroid on the grid.

    ``weights``: output label -> clip level (> 0). Returns 0 if nothing fires. The sums run
    over the grid in ascending order, skipping the points where no set reaches (the order of
    the C build's sums: the same floats).
    """
    if not weights:
        return 0.0
    lo, hi = len(GRID), 0
    for label in weights:
        if _FIRST[label] < lo:
            lo = _FIRST[label]
        if _END[label] > hi:
            hi = _END[label]
    mu = [0.0] * (hi - lo)
    for label, w in weights.items():
        j = _FIRST[label] - lo          # a support is contiguous (checked below the tables)
        for m in _MU[label]:
            if m > w:
                m = w
            if m > mu[j]:
                mu[j] = m
            j += 1
    num = den = 0.0
    for x, m in zip(GRID[lo:hi], mu, strict=True):
        if m > 0.0:
            num += x * m
            den += m
    return num / den if den > 0.0 else 0.0


def fuzzy_gains(e: float, ec: float) -> tuple[float, float, float]:
    """(Up, Ui, Ud), each in [-3, 3], for scaled inputs E, EC (clamped to [-6, 6])."""
    wp: dict[int, float] = {}
    wi: dict[int, float] = {}
    wd: dict[int, float] = {}
    ec_sets = active_sets(ec)
    for i, mi in active_sets(e):
        row = RULES[i]
        for k, mk in ec_sets:
            w = mi if mi < mk else mk
            lp, li, ld = row[k]
            if w > wp.get(lp, 0.0):
                wp[lp] = w
            if w > wi.get(li, 0.0):
                wi[li] = w
            if w > wd.get(ld, 0.0):
                wd[ld] = w
    return centroid(wp), centroid(wi), centroid(wd)
