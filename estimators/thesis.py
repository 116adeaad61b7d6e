"""The thesis's planar formulas (the "baseline method") and its chapter-4 / appendix-A tables.

Source: the master's thesis in ``../shared/seed/`` (chapter 3, eq. 3.1-3.13; chapter 4, Tables
4.2-4.15; appendix A, Tables A.1-A.3). Lengths are in whatever unit ``d`` is given in (the tables are
in centimetres: CONVENTIONS.md allows cm where the thesis is reproduced); angles are in degrees, as
the thesis writes them, and named ``*_deg``.

Conventions worked out from the text (see ``fisheye-des thesis``):
- theta1 is the interior angle of the triangle at the first camera/pose A (between A->B and A->C),
  theta2 the interior angle at the second camera/pose B (between B->A and B->C). With those,
  eq. 3.8 ``Y = d sin th1 / cos(th1 + th2 - 90)`` is the law of sines ``|BC| = d sin th1 / sin(th1 +
  th2)``: the range from B (the drone now / the right camera).
- The "Experimental Distance" of a table is computed from the "Degree of Angles (Experimental)" row;
  the "Measured" angles and distances are the ground truth read off the set-up.
- "Percentage Error" = |experimental - measured| / measured * 100, against the measured distance of
  the second figure (from B).

``reproduce()`` recomputes every table from its own inputs with the general estimators of
``estimators.geometry`` (``planar_triangulate``, ``planar_moving_obstacle_bounds``,
``velocity_from_fixes``), and ``inconsistencies()`` lists where the thesis disagrees with itself.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field

from estimators import geometry as geo

__all__ = [
    "ThesisTest",
    "TESTS",
    "ANGLE_ERROR_SUMMARY",
    "SPEED_TEST",
    "Row",
    "eq_3_1_stereo_Z",
    "eq_3_2_stereo_CF",
    "eq_3_3_parallel_slower_obstacle",
    "eq_3_4_parallel_faster_obstacle",
    "eq_3_5_nonparallel_slower_obstacle",
    "eq_3_6_nonparallel_faster_obstacle",
    "eq_3_6_as_printed",
    "eq_3_7_spacing",
    "eq_3_8_mono_Y",
    "eq_3_9_mono_CB",
    "eq_3_10_mono_CB",
    "eq_3_11_FB",
    "eq_3_12_BG",
    "eq_3_12_BG_corrected",
    "along_baseline_distances",
    "percentage_error",
    "reproduce",
    "table_summary",
    "inconsistencies",
]


def _s(a_deg: float) -> float:
    return math.sin(math.radians(a_deg))


def _c(a_deg: float) -> float:
    return math.cos(math.radians(a_deg))


def _t(a_deg: float) -> float:
    return math.tan(math.radians(a_deg))


# --------------------------------------------------------------------------- chapter 3, as printed

#: |sin(theta1 + theta2)| below this is no triangle (the rays parallel): the printed formulas divide by
#: it (cos(th1 + th2 - 90), tan(180 - th1 - th2)) and gave ~1e16 or ZeroDivisionError there
_PARALLEL_SIN = 1e-12


def _parallel(theta1_deg: float, theta2_deg: float) -> geo.Unobservable | None:
    """Unobservable when the two rays are parallel (theta1 + theta2 = 180 deg: no triangle), else None."""
    if abs(_s(theta1_deg + theta2_deg)) < _PARALLEL_SIN:
        return geo.Unobservable(
            f"parallel rays (theta1 + theta2 = {theta1_deg + theta2_deg:g} deg): no triangle, no range"
        )
    return None


def eq_3_1_stereo_Z(d: float, theta1_deg: float, theta2_deg: float) -> float | geo.Unobservable:
    """Eq. 3.1: perpendicular distance from the camera baseline, Z = d sin th1 sin th2 / cos(th1 + th2 - 90).

    Signed: negative when th1 + th2 > 180 deg (the rays diverge; the thesis then reports |Z|);
    Unobservable at th1 + th2 = 180 deg (parallel rays).
    """
    if (u := _parallel(theta1_deg, theta2_deg)) is not None:
        return u
    return d * _s(theta1_deg) * _s(theta2_deg) / _c(theta2_deg + theta1_deg - 90.0)


def eq_3_2_stereo_CF(
    d: float, theta1_deg: float, theta2_deg: float, *, as_printed: bool = False
) -> float | geo.Unobservable:
    """Eq. 3.2: distance from the baseline's midpoint F to the obstacle C, derived for th1 > 90 deg.

    CB = sin th2 AB / tan(180 - th1 - th2) + cos th2 AB, theta3 = 180 - th1 - th2,
    theta4 = 90 - th2 - th3, CF = sqrt((sin th2 CB)^2 + (CB sin th2 tan th4 + d/2)^2).
    ``as_printed=True`` uses the printed "tan(9 deg - th2 - th3)" instead of 90 deg (a typo).
    Unobservable at th1 + th2 = 180 deg (parallel rays).
    """
    if (u := _parallel(theta1_deg, theta2_deg)) is not None:
        return u
    th3 = 180.0 - theta1_deg - theta2_deg
    cb = _s(theta2_deg) * d / _t(th3) + _c(theta2_deg) * d
    th4 = (9.0 if as_printed else 90.0) - theta2_deg - th3
    return math.sqrt((_s(theta2_deg) * cb) ** 2 + (cb * _s(theta2_deg) * _t(th4) + 0.5 * d) ** 2)


def eq_3_3_parallel_slower_obstacle(AB: float, AC: float, BD: float, theta1_deg: float, theta2_deg: float):
    """Eq. 3.3: obstacle displacement CD = AB - AC cos th1 - BD cos th2 (motion parallel to the drone)."""
    return AB - AC * _c(theta1_deg) - BD * _c(theta2_deg)


def eq_3_4_parallel_faster_obstacle(AB: float, AC: float, BD: float, theta1_deg: float, theta2_deg: float):
    """Eq. 3.4: CD = AB + cos(180 - th2) BD - cos th1 AC (parallel motion, obstacle faster)."""
    return AB + _c(180.0 - theta2_deg) * BD - _c(theta1_deg) * AC


def eq_3_5_nonparallel_slower_obstacle(AB, AC, BD, theta1_deg, theta2_deg) -> float:
    """Eq. 3.5: CD = sqrt((AB - cos th1 AC - cos th2 BD)^2 + (sin th2 BD - sin th1 AC)^2)."""
    return math.hypot(
        AB - _c(theta1_deg) * AC - _c(theta2_deg) * BD, _s(theta2_deg) * BD - _s(theta1_deg) * AC
    )


def eq_3_6_nonparallel_faster_obstacle(AB, AC, BD, theta1_deg, theta2_deg) -> float:
    """Eq. 3.6 as derived: CD = sqrt((AB + cos(180-th2) BD - cos th1 AC)^2
    + (sin(180-th2) BD - sin th1 AC)^2)."""
    return math.hypot(
        AB + _c(180.0 - theta2_deg) * BD - _c(theta1_deg) * AC,
        _s(180.0 - theta2_deg) * BD - _s(theta1_deg) * AC,
    )


def eq_3_6_as_printed(AB, AC, BD, theta1_deg, theta2_deg) -> float:
    """Eq. 3.6 as printed: the square root split over the sum, sqrt(a^2) + sqrt(b^2) = |a| + |b|."""
    a = AB + _c(180.0 - theta2_deg) * BD - _c(theta1_deg) * AC
    b = _s(180.0 - theta2_deg) * BD - _s(theta1_deg) * AC
    return abs(a) + abs(b)


def eq_3_7_spacing(dt_s: float, drone_speed: float) -> float:
    """Eq. 3.7: d = time interval * speed of drone (units of speed * s)."""
    return dt_s * drone_speed


def eq_3_8_mono_Y(d: float, theta1_deg: float, theta2_deg: float) -> float | geo.Unobservable:
    """Eq. 3.8: range from the second pose, Y = d sin th1 / cos(th1 + th2 - 90) (= law of sines);
    Unobservable at th1 + th2 = 180 deg (parallel rays)."""
    if (u := _parallel(theta1_deg, theta2_deg)) is not None:
        return u
    return d * _s(theta1_deg) / _c(theta2_deg + theta1_deg - 90.0)


def eq_3_9_mono_CB(d: float, theta1_deg: float, theta2_deg: float) -> float | geo.Unobservable:
    """Eq. 3.9 (th1 = angle CAB > 90): CB = sin(CBA) AB / tan(180 - CAB - CBA) + cos(CBA) AB;
    Unobservable at th1 + th2 = 180 deg (parallel rays)."""
    if (u := _parallel(theta1_deg, theta2_deg)) is not None:
        return u
    return _s(theta2_deg) * d / _t(180.0 - theta1_deg - theta2_deg) + _c(theta2_deg) * d


def eq_3_10_mono_CB(d: float, theta1_deg: float, theta2_deg: float) -> float | geo.Unobservable:
    """Eq. 3.10 (th2 = angle CBA > 90): CB = sin(CAB) AB / cos(CBA + CAB - 90) (brackets restored);
    Unobservable at th1 + th2 = 180 deg (parallel rays)."""
    if (u := _parallel(theta1_deg, theta2_deg)) is not None:
        return u
    return _s(theta1_deg) * d / _c(theta2_deg + theta1_deg - 90.0)


def eq_3_11_FB(CB: float, FC: float, theta4_deg: float) -> float:
    """Eq. 3.11: lower range bound FB = sqrt((sin th4 FC)^2 + (CB - cos th4 FC)^2), th4 = th1."""
    return math.hypot(_s(theta4_deg) * FC, CB - _c(theta4_deg) * FC)


def eq_3_12_BG(CB: float, CG: float, theta3_deg: float) -> float:
    """Eq. 3.12 as printed: upper range bound BG = sqrt(CB^2 + (sin th3 CG)^2) + cos th3 CG, th3 = th2."""
    return math.sqrt(CB**2 + (_s(theta3_deg) * CG) ** 2) + _c(theta3_deg) * CG


def eq_3_12_BG_corrected(CB: float, CG: float, theta3_deg: float) -> float:
    """Eq. 3.12 with the right triangle BIC solved correctly: BI = sqrt(CB^2 - CI^2) (CB is the
    hypotenuse, CI = sin th3 CG is a leg), BG = BI + GI = sqrt(CB^2 - (sin th3 CG)^2) + cos th3 CG
    (the law of cosines |C + CG u - B|). NaN-free: a leg longer than CB gives CB' = 0."""
    return math.sqrt(max(CB**2 - (_s(theta3_deg) * CG) ** 2, 0.0)) + _c(theta3_deg) * CG


def along_baseline_distances(CB: float, D: float, theta2_deg: float) -> tuple[float, float]:
    """Distances from B to C - D u and C + D u (u = unit A->B): what eq. 3.11-3.12 aim at.

    With the interior angle th2 at B, the angle at C between C->B and +u is th2 (alternate angles), so
    by the law of cosines |C -+ D u - B| = sqrt(CB^2 + D^2 +- 2 CB D cos th2). Returns (F side, G side).
    """
    return (
        math.sqrt(CB**2 + D**2 + 2 * CB * D * _c(theta2_deg)),
        math.sqrt(max(CB**2 + D**2 - 2 * CB * D * _c(theta2_deg), 0.0)),
    )


def percentage_error(estimate: float, truth: float) -> float:
    """The thesis's error definition: |estimate - truth| / truth * 100 (percent)."""
    return abs(estimate - truth) / truth * 100.0


# --------------------------------------------------------------------------- chapter 4 / appendix data


@dataclass(frozen=True)
class ThesisTest:
    """One table of chapter 4 / appendix A, as printed (centimetres, degrees, percent).

    measured_cm: "Measured Distance" of the first and second figure (from A and from B).
    angles_*_deg: (theta1 at A, theta2 at B) as printed in the "Measured" / "Experimental" rows.
    distance_cm, error_pct: the thesis's "Experimental Distance" and "Percentage Error".
    """

    table: str
    title: str
    kind: str  # "mono" (one camera, two poses) or "stereo" (two cameras)
    spacing_cm: float
    measured_cm: tuple[float, float]
    angles_measured_deg: tuple[float, float]
    angles_experimental_deg: tuple[float, float]
    distance_cm: float
    error_pct: float
    moved_cm: float | None = None
    error_pct_summary: float | None = None  # Table 4.10's copy of the distance error, if any


TESTS: tuple[ThesisTest, ...] = (
    ThesisTest("4.2", "DES-MFLC Test 1", "mono", 165.1, (426.9, 407.9), (78, 83), (72.5, 80), 341.1, 16.4),
    ThesisTest("4.3", "DES-MFLC Test 2", "mono", 139.7, (264.4, 222.3), (63, 88), (57.5, 86.67), 201.3, 9.44),
    ThesisTest(
        "4.4",
        "DES-MFLC moving test",
        "mono",
        127.0,
        (298.7, 210.1),
        (63, 80),
        (62.5, 77.5),
        194.6,
        7.31,
        moved_cm=76.2,
    ),
    ThesisTest(
        "4.5",
        "DES-BFLC 10.2 cm spacing",
        "stereo",
        10.2,
        (258.8, 257.6),
        (83, 87),
        (85, 84.6),
        141.9,
        78.27,
        error_pct_summary=78.17,
    ),
    ThesisTest(
        "4.6",
        "DES-BFLC 15.2 cm spacing",
        "stereo",
        15.2,
        (258.8, 256.3),
        (83, 86.5),
        (85, 84.8),
        85.7,
        66.57,
        error_pct_summary=66.57,
    ),
    ThesisTest(
        "4.7",
        "DES-BFLC 20.3 cm spacing",
        "stereo",
        20.3,
        (258.8, 256.5),
        (83, 87),
        (85, 85.8),
        127.1,
        50.49,
        error_pct_summary=50.49,
    ),
    ThesisTest(
        "4.8",
        "DES-BFLC 25.4 cm spacing",
        "stereo",
        25.4,
        (258.8, 255.5),
        (83, 88),
        (85, 87.5),
        193.9,
        24.14,
        error_pct_summary=24.14,
    ),
    ThesisTest(
        "4.9",
        "DES-BFLC 30.5 cm spacing",
        "stereo",
        30.5,
        (258.8, 255.8),
        (83, 89),
        (85, 88.3),
        260.3,
        1.75,
        error_pct_summary=1.75,
    ),
    ThesisTest(
        "4.11", "DES-BFLC Test 1", "stereo", 30.5, (332.5, 324.1), (76, 98), (72.5, 100.58), 240.0, 25.61
    ),
    ThesisTest(
        "4.12", "DES-BFLC Test 2", "stereo", 30.5, (229.9, 235.2), (85, 103), (73.3, 98.3), 199.8, 15.03
    ),
    ThesisTest(
        "4.13",
        "DES-BFLC moving test, first fix",
        "stereo",
        30.5,
        (199.6, 195.1),
        (102, 94),
        (79.2, 90.4),
        165.6,
        15.12,
    ),
    ThesisTest(
        "4.14",
        "DES-BFLC moving test, second fix",
        "stereo",
        30.5,
        (272.3, 274.6),
        (88, 87),
        (100, 87.5),
        229.9,
        16.24,
        moved_cm=63.5,
    ),
    ThesisTest(
        "A.1", "DES-MFLC Appendix Test 1", "mono", 152.4, (316.5, 293.4), (68, 84), (64.2, 82.5), 249.7, 14.9
    ),
    ThesisTest(
        "A.2", "DES-MFLC Appendix Test 2", "mono", 101.6, (211.3, 236.5), (88, 57), (83.3, 55.8), 154.2, 34.8
    ),
    ThesisTest(
        "A.3",
        "DES-MFLC Appendix Test 3",
        "mono",
        101.6,
        (423.9, 423.926),
        (81, 87),
        (82.9, 86.7),
        557.8,
        31.6,
    ),
)

# Table 4.10: spacing (cm) -> angle error left (%), angle error right (%), distance error (%)
ANGLE_ERROR_SUMMARY: dict[str, tuple[float, float, float]] = {
    "4.5": (2.41, 2.78, 78.17),
    "4.6": (2.41, 1.97, 66.57),
    "4.7": (2.41, 1.34, 50.49),
    "4.8": (2.41, 0.57, 24.14),
    "4.9": (2.41, 0.79, 1.75),
}

# Table 4.15: obstacle moved between the fixes of Tables 4.13 and 4.14, at 0.1 s per capture.
SPEED_TEST = {
    "moved_measured_cm": 63.5,
    "moved_experimental_cm": 59.6,
    "error_pct": 6.2,
    "speed_cm_per_s": 595.6,
    "dt_s": 0.1,
    "fixes": ("4.13", "4.14"),
}


# --------------------------------------------------------------------------- reproduction


@dataclass(frozen=True)
class Row:
    """One reproduced quantity: the thesis's value, ours, their difference and a verdict.

    verdict: "reproduces" (equal to the printed digits, or within the spread that rounding the
    printed inputs to their last digit causes) or "does not reproduce". ``ours`` is None when our
    estimator answers Unobservable (``note`` says why).
    """

    table: str
    quantity: str
    unit: str
    thesis: float | None
    ours: float | None
    diff: float | None
    tolerance: float
    verdict: str
    note: str = ""
    extra: dict = field(default_factory=dict)


def _decimals(x: float) -> int:
    r = repr(float(x))
    return 0 if r.endswith(".0") else len(r.split(".")[1])


def _half_unit(x: float, *, min_decimals: int = 0) -> float:
    """Half a unit of the last printed digit of ``x`` (e.g. 86.67 -> 0.005)."""
    return 0.5 * 10.0 ** (-max(_decimals(x), min_decimals))


def _mono_range_cm(d_cm: float, t1_deg: float, t2_deg: float) -> geo.Triangulation | geo.Unobservable:
    """Range from B via the general estimator (metres inside, centimetres at this edge)."""
    return geo.planar_triangulate(d_cm / 100.0, math.radians(t1_deg), math.radians(t2_deg))


def _range_spread_cm(d_cm, t1, t2) -> tuple[float, float] | None:
    """Min/max of our estimate over the rounding box of the printed inputs (8 corners)."""
    vals = []
    for sd, s1, s2 in itertools.product((-1, 1), repeat=3):
        dd = d_cm + sd * _half_unit(d_cm, min_decimals=1)
        a1 = t1 + s1 * _half_unit(t1, min_decimals=1)  # angles were read to 0.1 deg (or finer)
        a2 = t2 + s2 * _half_unit(t2, min_decimals=1)
        r = _mono_range_cm(dd, a1, a2)
        if isinstance(r, geo.Unobservable):
            return None
        vals.append(100.0 * r.range_m)
    return min(vals), max(vals)


def _verdict(thesis: float, ours: float | None, spread: tuple[float, float] | None, printed_half: float):
    """(diff, tolerance, verdict, how) for a thesis value against ours and our rounding spread."""
    if ours is None:
        return None, 0.0, "does not reproduce", "ours is unobservable"
    diff = thesis - ours
    if abs(diff) <= printed_half + 1e-9:
        return diff, printed_half, "reproduces", "to the printed digits"
    if spread is not None:
        lo, hi = spread
        tol = max(ours - lo, hi - ours) + printed_half
        if lo - printed_half <= thesis <= hi + printed_half:
            return diff, tol, "reproduces", "within the rounding of the printed inputs"
        return diff, tol, "does not reproduce", ""
    return diff, printed_half, "does not reproduce", ""


def _pct_spread(spread, truth, truth_half):
    """Min/max of |est - truth|/truth*100 over est in spread and truth +- its half unit."""
    if spread is None:
        return None
    vals = [percentage_error(e, t) for e in spread for t in (truth - truth_half, truth + truth_half)]
    lo_e, hi_e = spread
    if lo_e <= truth <= hi_e:
        vals.append(0.0)
    return min(vals), max(vals)


def _table_rows(t: ThesisTest) -> list[Row]:
    rows: list[Row] = []
    d, (t1, t2) = t.spacing_cm, t.angles_experimental_deg
    truth = t.measured_cm[1]
    res = _mono_range_cm(d, t1, t2)
    ours = None if isinstance(res, geo.Unobservable) else 100.0 * res.range_m
    spread = _range_spread_cm(d, t1, t2)
    dist_half = _half_unit(t.distance_cm, min_decimals=1)
    diff, tol, verdict, how = _verdict(t.distance_cm, ours, spread, dist_half)
    eq = "eq. 3.8/3.10 law of sines, range from " + ("pose B" if t.kind == "mono" else "camera B")
    note = (f"{eq}; {how}" if how else eq) if ours is not None else f"unobservable: {res.reason}"
    extra = {}
    if t.kind == "stereo" and ours is not None:
        extra = {
            "Z_eq_3_1_cm": 100.0 * float(res.p[1]),
            "CF_eq_3_2_cm": 100.0
            * geo.planar_triangulate(d / 100.0, math.radians(t1), math.radians(t2), origin="mid").range_m,
        }
    rows.append(
        Row(t.table, "experimental distance", "cm", t.distance_cm, ours, diff, tol, verdict, note, extra)
    )

    # percentage error against the second figure's measured distance
    pct_half = _half_unit(t.error_pct)
    ours_pct = None if ours is None else percentage_error(ours, truth)
    pspread = _pct_spread(spread, truth, _half_unit(truth, min_decimals=1))
    diff, tol, verdict, how = _verdict(t.error_pct, ours_pct, pspread, pct_half)
    own = percentage_error(t.distance_cm, truth)
    note = (
        (f"|est - {truth}| / {truth}" + (f"; {how}" if how else ""))
        if ours_pct is not None
        else f"unobservable: {res.reason}"
    )
    rows.append(
        Row(
            t.table,
            "percentage error",
            "%",
            t.error_pct,
            ours_pct,
            diff,
            tol,
            verdict,
            note,
            {"from_thesis_distance_pct": own},
        )
    )
    if t.error_pct_summary is not None and t.error_pct_summary != t.error_pct:
        diff, tol, verdict, how = _verdict(t.error_pct_summary, ours_pct, pspread, pct_half)
        rows.append(
            Row(
                "4.10",
                f"distance error ({t.spacing_cm} cm spacing)",
                "%",
                t.error_pct_summary,
                ours_pct,
                diff,
                tol,
                verdict,
                f"copy of Table {t.table}'s error; {how}",
            )
        )
    elif t.error_pct_summary is not None:
        rows.append(
            Row(
                "4.10",
                f"distance error ({t.spacing_cm} cm spacing)",
                "%",
                t.error_pct_summary,
                ours_pct,
                rows[-1].diff,
                rows[-1].tolerance,
                rows[-1].verdict,
                f"copy of Table {t.table}'s error",
            )
        )
    return rows


def _angle_error_rows() -> list[Row]:
    rows = []
    by_table = {t.table: t for t in TESTS}
    for table, (left, right, _dist) in ANGLE_ERROR_SUMMARY.items():
        t = by_table[table]
        for side, thesis_pct, meas, exp in (
            ("left", left, t.angles_measured_deg[0], t.angles_experimental_deg[0]),
            ("right", right, t.angles_measured_deg[1], t.angles_experimental_deg[1]),
        ):
            ours = percentage_error(exp, meas)  # |experimental - measured| / measured
            half = _half_unit(thesis_pct)
            diff, tol, verdict, how = _verdict(thesis_pct, ours, None, half)
            rows.append(
                Row(
                    "4.10",
                    f"angle error {side} ({t.spacing_cm} cm spacing)",
                    "%",
                    thesis_pct,
                    ours,
                    diff,
                    tol,
                    verdict,
                    f"|{exp} - {meas}| / {meas}" + (f"; {how}" if how else ""),
                )
            )
    return rows


def _moving_mono_rows() -> list[Row]:
    """Table 4.4 (moving obstacle, mono): static estimate plus our bounds and the thesis's FB/BG."""
    t = next(x for x in TESTS if x.table == "4.4")
    d, (t1, t2) = t.spacing_cm, t.angles_experimental_deg
    truth = t.measured_cm[1]
    rows = []
    cb = 100.0 * _mono_range_cm(d, t1, t2).range_m
    for label, D in (("measured motion", t.moved_cm), ("thesis: = drone's", d)):
        b = geo.planar_moving_obstacle_bounds(d / 100.0, math.radians(t1), math.radians(t2), D / 100.0)
        if isinstance(b, geo.Unobservable):
            rows.append(
                Row(
                    t.table,
                    f"bounds, D = {D} cm ({label})",
                    "cm",
                    None,
                    None,
                    None,
                    0.0,
                    "does not reproduce",
                    f"unobservable: {b.reason}",
                )
            )
            continue
        lo = 100.0 * b.range_min_m
        hi = None if b.range_max_m is None else 100.0 * b.range_max_m
        inside = lo <= truth and (hi is None or truth <= hi)
        rows.append(
            Row(
                t.table,
                f"bounds, D = {D} cm ({label})",
                "cm",
                None,
                lo,
                None,
                0.0,
                "new (not in the thesis)",
                f"[{lo:.1f}, {'inf' if hi is None else f'{hi:.1f}'}] cm; measured {truth} cm "
                + ("inside" if inside else "OUTSIDE"),
                {"range_min_cm": lo, "range_max_cm": hi, "truth_inside": inside},
            )
        )
    fb = eq_3_11_FB(cb, d, t1)
    bg = eq_3_12_BG(cb, d, t2)
    bgc = eq_3_12_BG_corrected(cb, d, t2)
    f_side, g_side = along_baseline_distances(cb, d, t2)
    rows.append(
        Row(
            t.table,
            "thesis bounds eq. 3.11-3.12 (FC = GC = AB)",
            "cm",
            None,
            None,
            None,
            0.0,
            "new (not in the thesis)",
            f"CB = {cb:.1f}, FB = {fb:.1f}, BG as printed = {bg:.1f} (right triangle corrected {bgc:.1f}), "
            f"|C -+ AB u - B| = {f_side:.1f}, {g_side:.1f}; measured {truth} "
            + ("inside" if fb <= truth <= bg else "OUTSIDE")
            + " [FB, BG]",
            {
                "CB_cm": cb,
                "FB_cm": fb,
                "BG_cm": bg,
                "BG_corrected_cm": bgc,
                "F_side_cm": f_side,
                "G_side_cm": g_side,
            },
        )
    )
    return rows


def _speed_rows() -> list[Row]:
    """Table 4.15: moved distance and speed from the two stereo fixes of Tables 4.13 and 4.14."""
    by_table = {t.table: t for t in TESTS}
    fixes = []
    for key in SPEED_TEST["fixes"]:
        t = by_table[key]
        fixes.append(_mono_range_cm(t.spacing_cm, *t.angles_experimental_deg))
    rows = []
    if any(isinstance(f, geo.Unobservable) for f in fixes):
        why = "; ".join(
            f"Table {k}: {f.reason}"
            for k, f in zip(SPEED_TEST["fixes"], fixes, strict=True)
            if isinstance(f, geo.Unobservable)
        )
        vel = geo.Unobservable(f"a fix is unobservable ({why})")
    else:
        vel = geo.velocity_from_fixes(fixes[0].p, 0.0, fixes[1].p, SPEED_TEST["dt_s"])
    moved = None if isinstance(vel, geo.Unobservable) else 100.0 * vel.speed_mps * SPEED_TEST["dt_s"]
    speed = None if isinstance(vel, geo.Unobservable) else 100.0 * vel.speed_mps
    note = "" if moved is not None else f"unobservable: {vel.reason}"
    for q, thesis, ours, unit in (
        ("moved distance (experimental)", SPEED_TEST["moved_experimental_cm"], moved, "cm"),
        ("speed of obstacle", SPEED_TEST["speed_cm_per_s"], speed, "cm/s"),
    ):
        diff, tol, verdict, how = _verdict(thesis, ours, None, _half_unit(thesis, min_decimals=1))
        rows.append(Row("4.15", q, unit, thesis, ours, diff, tol, verdict, note or how))
    ours_pct = None if moved is None else percentage_error(moved, SPEED_TEST["moved_measured_cm"])
    diff, tol, verdict, how = _verdict(SPEED_TEST["error_pct"], ours_pct, None, 0.05)
    rows.append(
        Row(
            "4.15",
            "percentage error (moved distance)",
            "%",
            SPEED_TEST["error_pct"],
            ours_pct,
            diff,
            tol,
            verdict,
            note or how,
            {
                "from_thesis_moved_pct": percentage_error(
                    SPEED_TEST["moved_experimental_cm"], SPEED_TEST["moved_measured_cm"]
                )
            },
        )
    )
    return rows


def reproduce() -> list[Row]:
    """Recompute every numeric table of chapter 4 and appendix A from its own inputs."""
    rows: list[Row] = []
    for t in TESTS:
        rows.extend(_table_rows(t))
        if t.table == "4.4":
            rows.extend(_moving_mono_rows())
    rows.extend(_angle_error_rows())
    rows.extend(_speed_rows())
    rows.extend(_spacing_rows())
    return rows


def _spacing_rows() -> list[Row]:
    """Section 4.1.2: 30-40 mph in cm/s and the spacing per 0.1 s (eq. 3.7)."""
    rows = []
    cm_per_s_per_mph = 160934.4 / 3600.0  # 1 mile = 160934.4 cm exactly
    for mph, speed_printed, spacing_printed in ((30, 1341.1, 134.1), (40, 1788.2, 178.8)):
        v = mph * cm_per_s_per_mph
        for q, thesis, ours, unit in (
            (f"{mph} mph", speed_printed, v, "cm/s"),
            (f"spacing at {mph} mph, 0.1 s (eq. 3.7)", spacing_printed, eq_3_7_spacing(0.1, v), "cm"),
        ):
            diff, tol, verdict, how = _verdict(thesis, ours, None, _half_unit(thesis, min_decimals=1))
            rows.append(Row("sec 4.1.2", q, unit, thesis, ours, diff, tol, verdict, how))
    return rows


def _stereo_definition_line() -> str:
    """Which stereo distance (eq. 3.1 Z, eq. 3.8 Y, eq. 3.2 CF) each binocular table printed."""
    picks: dict[str, list[str]] = {}
    for t in TESTS:
        if t.kind != "stereo":
            continue
        d, (t1, t2) = t.spacing_cm, t.angles_experimental_deg
        cand = {
            "Y (eq. 3.8)": abs(eq_3_8_mono_Y(d, t1, t2)),
            "|Z| (eq. 3.1)": abs(eq_3_1_stereo_Z(d, t1, t2)),
            "CF (eq. 3.2)": eq_3_2_stereo_CF(d, t1, t2),
        }
        errs = {k: abs(v - t.distance_cm) for k, v in cand.items()}
        best = min(errs, key=errs.get)
        close = [k for k, e in errs.items() if e <= errs[best] + 0.05]
        if errs[best] > 0.05 * t.distance_cm:
            label = "none of them"
        elif len(close) > 1:
            label = " = ".join(close)
        else:
            label = best
        picks.setdefault(label, []).append(t.table)
    listing = "; ".join(f"{k}: {', '.join(v)}" for k, v in picks.items())
    return (
        "sections 4.2.4-4.2.5: chapter 3 defines the stereo distance as Z (eq. 3.1, perpendicular to the "
        "baseline), but the printed binocular distances are closest to: " + listing + " (Z = Y sin th2 "
        "differs from Y by < 0.5% except in 4.11 (1.7%) and 4.12 (1.1%))"
    )


def _measured_triangle_line() -> str:
    """Do the 'measured' angles fit the measured distances of the mono tests (static obstacle)?"""
    parts = []
    worst = 0.0
    for t in TESTS:
        if t.kind != "mono" or t.moved_cm is not None:
            continue
        a, b, d = t.measured_cm[0], t.measured_cm[1], t.spacing_cm
        # interior angles of the triangle with sides |AC| = a, |BC| = b, |AB| = d (law of cosines)
        ang_a = math.degrees(math.acos((a * a + d * d - b * b) / (2 * a * d)))
        ang_b = math.degrees(math.acos((b * b + d * d - a * a) / (2 * b * d)))
        y = eq_3_8_mono_Y(d, *t.angles_measured_deg)
        worst = max(worst, percentage_error(y, b))
        parts.append(
            f"{t.table}: measured angles {t.angles_measured_deg[0]:g}/{t.angles_measured_deg[1]:g} give "
            f"{y:.1f} cm for measured {b:g} cm; the measured sides imply {ang_a:.1f}/{ang_b:.1f} deg"
        )
    return (
        "the 'measured' angles of the mono tests do not fit their measured distances (eq. 3.8 on them "
        f"misses by up to {worst:.0f}%), so the ground truth itself carries several degrees of angle "
        "error: " + "; ".join(parts)
    )


def inconsistencies() -> list[str]:
    """One line per place where the thesis disagrees with itself, each with the explanation.

    The numbers in the lines are computed here, from the thesis's own printed values.
    """
    by = {t.table: t for t in TESTS}
    out: list[str] = []
    # chapter 3
    out.append(
        "eq. 3.2: prints tan(9 deg - th2 - th3); the derivation (th4 = 90 - th2 - th3) needs 90 deg. "
        f"Table 4.11 inputs: as printed {eq_3_2_stereo_CF(30.5, 100.58, 72.5, as_printed=True):.1f} cm, "
        f"with 90 deg {eq_3_2_stereo_CF(30.5, 100.58, 72.5):.1f} cm"
    )
    out.append(
        "eq. 3.3: the derivation writes BF = sin(th2) BD but then uses BD cos(th2) (the cosine is right)"
    )
    a, ac, bd, x1, x2 = 30.5, 165.6, 229.9, 79.2, 87.5
    out.append(
        "eq. 3.6: the square root of a sum of squares is split into a sum of square roots (|a| + |b|, "
        f"not sqrt(a^2 + b^2)); e.g. AB={a}, AC={ac}, BD={bd}, th1={x1}, th2={x2}: "
        f"{eq_3_6_as_printed(a, ac, bd, x1, x2):.1f} vs "
        f"{eq_3_6_nonparallel_faster_obstacle(a, ac, bd, x1, x2):.1f}"
    )
    out.append(
        "eq. 3.8: Step 1 writes X = d cos th1 but Step 4 uses d sin th1 (the sine is right: it is the "
        "law of sines |BC| = d sin th1 / sin(th1 + th2))"
    )
    out.append("eq. 3.9: the text writes CB = CE + CB; the derivation needs CB = CE + BE")
    out.append(
        "eq. 3.10: printed cos(CBA) + CAB - 90; the brackets belong around the whole angle, "
        "cos(CBA + CAB - 90)"
    )
    cb = eq_3_8_mono_Y(127.0, 62.5, 77.5)
    out.append(
        "eq. 3.12: BI = sqrt(CB^2 + CI^2) should be sqrt(CB^2 - CI^2) (CB is the hypotenuse of the right "
        f"triangle BIC); Table 4.4 inputs (CB = {cb:.1f}, CG = 127): printed "
        f"{eq_3_12_BG(cb, 127, 77.5):.1f}, corrected {eq_3_12_BG_corrected(cb, 127, 77.5):.1f} cm"
    )
    fb, bg = along_baseline_distances(cb, 127.0, 77.5)
    out.append(
        "eq. 3.11-3.12 take the angles at C and G equal to th1 and th2; with FG parallel to AB the angle "
        "between CB and FG is th2 (alternate angles), so |C -+ FC u - B| = "
        f"{fb:.1f}, {bg:.1f} cm for Table 4.4 (eq. 3.11: {eq_3_11_FB(cb, 127.0, 62.5):.1f}); and both "
        "ignore that the second bearing puts the obstacle on ray b (geometry.moving_obstacle_bounds uses "
        "both rays and any direction of motion)"
    )
    # chapter 4 text and tables
    out.append(
        "section 4.2.1: says Table 4.2's distance uses eq. 3.2 (the stereo midpoint range for an angle over "
        f"90 deg); the printed 341.1 is eq. 3.8 ({eq_3_8_mono_Y(165.1, 72.5, 80):.2f}); eq. 3.2 would give "
        f"{eq_3_2_stereo_CF(165.1, 72.5, 80):.1f}"
    )
    out.append(_stereo_definition_line())
    t = by["4.5"]
    y = eq_3_8_mono_Y(t.spacing_cm, *t.angles_experimental_deg)
    out.append(
        f"Table 4.5: the distance {t.distance_cm} cm contradicts its own error {t.error_pct}% "
        f"(|141.9 - 257.6|/257.6 = {percentage_error(141.9, 257.6):.2f}%); the inputs give {y:.1f} cm "
        f"({percentage_error(y, 257.6):.2f}%), and Table 4.10 prints {t.error_pct_summary}% for this row"
    )
    t = by["4.3"]
    out.append(
        f"Table 4.3: {t.error_pct}% from its own {t.distance_cm} cm is "
        f"{percentage_error(t.distance_cm, t.measured_cm[1]):.3f}% (truncated instead of rounded); "
        "the text quotes 86.7 deg for the table's 86.67 deg"
    )
    for t in TESTS:  # the percentage error recomputed from the table's own printed distance
        own = percentage_error(t.distance_cm, t.measured_cm[1])
        # tolerance: half a unit of the printed percentage + the effect of rounding the distance to 0.05 cm
        tol = _half_unit(t.error_pct) + 100 * 0.05 / t.measured_cm[1]
        if t.table != "4.5" and abs(own - t.error_pct) > tol:
            implied = t.measured_cm[1] * (1 - t.error_pct / 100)
            out.append(
                f"Table {t.table}: its error {t.error_pct}% does not follow from its own distance "
                f"{t.distance_cm} cm ({own:.2f}%); it implies {implied:.1f} cm"
            )
    t = by["4.4"]
    out.append(
        f"Table 4.4: the moving-test distance {t.distance_cm} cm does not follow from its inputs by any "
        f"chapter-3 equation (eq. 3.8 gives {eq_3_8_mono_Y(127, 62.5, 77.5):.1f} cm; eq. 3.11/3.12 are "
        "bounds, not a value); the measured angles/distances are consistent with the stated 76.2 cm motion "
        "(the measured positions differ by 74.4 cm)"
    )
    out.append(
        "Table 4.10: right angle errors 2.78% and 1.34% should be "
        f"{percentage_error(84.6, 87):.2f}% and {percentage_error(85.8, 87):.2f}% "
        "(|84.6 - 87|/87, |85.8 - 87|/87); the other eight follow |exp - meas|/meas"
    )
    out.append("Table 4.10: the 10.2 cm distance error 78.17% differs from Table 4.5's 78.27%")
    out.append(
        "Table 4.13: measured angles 102 + 94 = 196 deg cannot both be interior angles; the measured "
        "distances give interior angles 77.2 and 94.1 deg, so 102 is the exterior angle (180 - 78)"
    )
    t = by["4.14"]
    z = eq_3_1_stereo_Z(t.spacing_cm, *t.angles_experimental_deg)
    out.append(
        f"Table 4.14: experimental angles 100 + 87.5 = 187.5 deg >= 180: the rays diverge (unobservable); "
        f"eq. 3.1 gives Z = {z:.1f} cm (negative) and the thesis prints its magnitude {t.distance_cm}"
    )
    out.append(
        "Table 4.15: no chapter-3 equation gives the moved distance 59.6 cm from the printed fixes "
        f"(165.6 and 229.9 cm); the error 6.2% and speed 595.6 cm/s imply an unrounded 59.56 cm "
        f"(from the printed 59.6: {percentage_error(59.6, 63.5):.2f}%); the difference of the two ranges "
        f"is {229.9 - 165.6:.1f} cm"
    )
    out.append(_measured_triangle_line())
    out.append("Tables 4.14, 4.15 are titled DES-MFLC but report the binocular (DES-BFLC) moving test")
    out.append(
        "section 4.1.2 sets the spacing to 134.1-178.8 cm (30-40 mph at 0.1 s), but Tables 4.4, A.2, A.3 use "
        "127.0 and 101.6 cm"
    )
    return out


def table_summary(rows: list[Row]) -> dict[str, str]:
    """Per table: "reproduces" when every compared quantity does, else the quantities that do not."""
    out: dict[str, list[str]] = {}
    for r in rows:
        if r.thesis is None:  # informational rows (our bounds), nothing to compare
            continue
        out.setdefault(r.table, [])
        if r.verdict != "reproduces":
            out[r.table].append(r.quantity)

    def order(k: str) -> tuple:  # "sec 4.1.2" < "4.2" < ... < "4.15" < "A.1" (thesis order)
        parts = k.removeprefix("sec ").split(".")
        key = tuple(-1 if p == "A" else int(p) for p in parts)
        return (parts[0] == "A", not k.startswith("sec "), key)

    return {
        k: "reproduces" if not out[k] else "does not reproduce: " + ", ".join(out[k])
        for k in sorted(out, key=order)
    }


def rows_as_dicts(rows: list[Row]) -> list[dict]:
    """Rows as plain JSON-ready dicts."""
    return [asdict(r) for r in rows]
