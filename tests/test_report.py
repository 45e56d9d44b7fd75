"""The report from synthetic rows (no measurement): matched speed-ups, the verdicts, the paper's
table, the wall time of the units; two reports of the same rows are the same bytes."""

from __future__ import annotations

import re
import time

import numpy as np
import pandas as pd
import pytest

from harness.report.files import write_report


def test_time_at_accuracy_interpolates_on_the_pareto_front():
    from harness.report.speedups import break_even, pareto_front, time_at_accuracy

    errors = np.array([1e-3, 1e-5, 1e-7, 1e-6])
    seconds = np.array([0.01, 0.1, 1.0, 2.0])  # the last point is dominated by 1e-7 in 1.0 s
    e, t = pareto_front(errors, seconds)
    np.testing.assert_array_equal(e, [1e-7, 1e-5, 1e-3])
    np.testing.assert_array_equal(t, [1.0, 0.1, 0.01])
    assert time_at_accuracy(errors, seconds, 1e-4) == (pytest.approx(np.sqrt(0.1 * 0.01)), "interpolated")
    assert time_at_accuracy(errors, seconds, 1e-2) == (0.01, "at most")
    assert np.isnan(time_at_accuracy(errors, seconds, 1e-9)[0])
    assert break_even(10.0, 0.5, 0.1) == pytest.approx(25.0)
    assert break_even(10.0, 0.1, 0.5) == float("inf")


def _report_rows() -> list[dict]:
    """Synthetic rows of a trained adapter and a classical one on the SMIB: fit, accuracy, latency
    and work-precision."""
    base = {"case": "smib-inference", "variant": "", "threads": 2, "status": "ok"}
    pinn = {**base, "solver": "toy-pinn", "config": "default", "seed": 0, "trains": True}
    ode = {**base, "solver": "scipy-odeint", "config": "default", "seed": -1, "trains": False}
    return [
        {"suite": "fit", **pinn, "fit_s": 50.0, "iterations": 100, "loss": 1e-6, "message": ""},
        {"suite": "fit", **ode, "fit_s": 1e-5, "iterations": 0, "loss": np.nan, "message": ""},
        {"suite": "accuracy", **pinn, "quantity": "delta", "against": "reference", "rel_l2": 1e-3, "max_abs": 1e-3,
         "worst_trajectory_rel_l2": 2e-3},
        {"suite": "accuracy", **ode, "quantity": "delta", "against": "reference", "rel_l2": 1e-4, "max_abs": 1e-4,
         "worst_trajectory_rel_l2": 2e-4},
        {"suite": "latency", **pinn, "kind": "grid", "query": "grid 100x201", "median_s": 0.002, "q25_s": 0.002,
         "q75_s": 0.002, "min_s": 0.002, "repeats": 5},
        {"suite": "latency", **ode, "kind": "grid", "query": "grid 100x201", "median_s": 0.004, "q25_s": 0.004,
         "q75_s": 0.004, "min_s": 0.004, "repeats": 5},
        {"suite": "work_precision", **pinn, "rel_l2_delta": 1e-3, "median_s": 0.002},
        *({"suite": "work_precision", **ode, "rtol": r, "atol": r * 1e-3, "rel_l2_delta": e, "median_s": s}
          for r, e, s in ((1e-3, 1e-2, 0.001), (1e-6, 1e-5, 0.004))),
    ]


def test_report_compares_a_trained_adapter_with_the_classical_ones(tmp_path):
    """Synthetic rows (no measurement): the report's verdicts follow the numbers."""
    rows = _report_rows()
    (tmp_path / "figure3-wscc9.png").write_bytes(b"a plot of an earlier run's case")
    (tmp_path / "notes.png").write_bytes(b"not a plot of ours")
    markdown = write_report(rows, tmp_path, {"threads": 2}, plots=True)
    assert not (tmp_path / "figure3-wscc9.png").exists() and (tmp_path / "notes.png").exists()
    # PINN query 2 ms vs 4 ms classical at least as accurate: N* = 50 / (0.004 - 0.002) = 25,000
    assert "25,000" in markdown
    # on the work-precision curve the classical time at 1e-3 is 4 ms * 4^(-2/3) = 1.59 ms: 0.794x
    assert "0.794x" in markdown
    assert "toy-pinn default" in markdown and "scipy-odeint default" in markdown
    assert (tmp_path / "work_precision.png").exists() and (tmp_path / "tables.tex").exists()
    assert "![work_precision](work_precision.png)" in (tmp_path / "README.md").read_text()


def test_two_reports_of_the_same_rows_are_the_same_bytes(tmp_path):
    """PDFs included: they carry no creation date (PDF dates have whole seconds: the reports are
    written more than a second apart)."""
    def report(folder):
        write_report(_report_rows(), folder, {"threads": 2}, plots=True)
        return {p.name: p.read_bytes() for p in folder.iterdir()}

    first = report(tmp_path / "a")
    time.sleep(1.1)
    assert {"work_precision.pdf", "work_precision.png", "tables.md"} <= set(first)
    assert report(tmp_path / "b") == first


@pytest.mark.parametrize("classical_s,verdict", [
    (0.004, "2x faster than best Python-driven (scipy-odeint [default])"),
    (0.001, "2x slower than best Python-driven (scipy-odeint [default])"),
])
def test_paper_table_says_who_wins_at_matched_accuracy(classical_s, verdict):
    from harness.report.frames import suite_frames
    from harness.report.paper import paper_table

    base = {"case": "smib-inference", "variant": "", "threads": 2, "status": "ok"}
    pinn = {**base, "solver": "toy-pinn", "config": "default", "seed": 0, "trains": True}
    ode = {**base, "solver": "scipy-odeint", "config": "default", "seed": -1, "trains": False}
    rows = [
        {"suite": "accuracy", **pinn, "quantity": "delta", "against": "reference", "rel_l2": 1e-3},
        {"suite": "accuracy", **ode, "quantity": "delta", "against": "reference", "rel_l2": 1e-4},
        {"suite": "latency", **pinn, "kind": "grid", "query": "grid 100x201", "median_s": 0.002},
        {"suite": "latency", **ode, "kind": "grid", "query": "grid 100x201", "median_s": classical_s},
    ]
    table = paper_table(suite_frames(rows)).set_index("claim")
    shows = table.loc["100 trajectories, delta and omega on 100 x 201, warm", "what it shows"]
    assert shows.startswith("at matched accuracy (seed 0): toy-pinn [default] (0.002 s at rel. L2 0.001)")
    assert verdict in shows
    assert "literature baseline: none as accurate" in shows and "best compiled: none as accurate" in shows


def test_fastest_classical_includes_the_tolerance_sweep():
    """The rival of a PINN is the fastest classical option at least as accurate: a named config
    or any point of the work-precision sweep, for the grid and for the single-point query."""
    from harness.report.frames import suite_frames
    from harness.report.ladder import GRID_QUERY, POINT_QUERY, fastest_classical

    base = {"case": "smib-inference", "threads": 2, "status": "ok", "seed": -1}
    ode = {**base, "solver": "scipy-odeint", "config": "default", "variant": ""}
    rk = {**base, "solver": "scipy-rk45", "config": "tight", "variant": "batch=stacked"}
    rows = [
        {"suite": "accuracy", **ode, "quantity": "delta", "against": "reference", "rel_l2": 3e-4},
        {"suite": "accuracy", **rk, "quantity": "delta", "against": "reference", "rel_l2": 1e-11},
        *({"suite": "latency", **spec, "query": q, "median_s": s}
          for spec, q, s in ((ode, GRID_QUERY, 0.006), (ode, POINT_QUERY, 5e-4),
                             (rk, GRID_QUERY, 0.030), (rk, POINT_QUERY, 1e-2))),
        *({"suite": "work_precision", **rk, "rtol": r, "atol": r * 1e-3, "rel_l2_delta": e, "median_s": s,
           "point_median_s": p}
          for r, e, s, p in ((1e-4, 3e-5, 0.003, 2e-3), (1e-6, 1.5e-7, 0.006, 4e-3))),
    ]
    frames = suite_frames(rows)
    assert fastest_classical(frames, GRID_QUERY, 1e-3) == ("scipy-rk45 [tight, batch=stacked, rtol=0.0001, atol=1e-07]",
                                                           0.003)
    assert fastest_classical(frames, GRID_QUERY, 1e-6) == ("scipy-rk45 [tight, batch=stacked, rtol=1e-06, atol=1e-09]",
                                                           0.006)
    assert fastest_classical(frames, GRID_QUERY, 1e-9) == ("scipy-rk45 [tight, batch=stacked]", 0.030)
    assert fastest_classical(frames, POINT_QUERY, 1e-3) == ("scipy-odeint [default]", 5e-4)
    assert fastest_classical(frames, POINT_QUERY, 1e-4) == ("scipy-rk45 [tight, batch=stacked, rtol=0.0001, atol=1e-07]",
                                                            2e-3)
    assert fastest_classical(frames, POINT_QUERY, 1e-12) is None


def test_work_minutes_sums_each_unit_once_and_says_when_some_have_no_time():
    from harness.report.markdown import work_minutes

    unit = {"suite": "latency", "solver": "a", "config": "default", "variant": "", "seed": -1}
    rows = [{**unit, "case": "x", "work_s": 60.0}, {**unit, "case": "x", "work_s": 60.0},  # one unit, two rows
            {**unit, "case": "y", "work_s": 30.0}]
    assert work_minutes(rows) == "Wall time of its units of work, minutes: x 1.0, y 0.5; 1.5 in all.\n\n"
    older = {**unit, "solver": "b", "case": "x"}
    assert "(only 2 of its 3 units recorded it" in work_minutes([*rows, older])
    assert work_minutes([older]) == ""


def test_rows_of_runs_before_the_trains_column_are_read_by_their_seeds():
    """Runs before rows declared `trains` gave trained adapters seeds >= 0 and the others -1: their
    tables (results/full-identification) must read as they did."""
    from harness.report.frames import trained

    old = pd.DataFrame({"solver": ["jax-pinn", "numba-rk"], "seed": [0, -1]})
    assert trained(old).tolist() == [True, False]
    new = pd.DataFrame({"solver": ["jax-pinn", "numba-rk", "gone"], "seed": [0, -1, 0], "trains": [True, False, None]})
    assert trained(new).tolist() == [True, False, False]


# The figures and pages, from small synthetic rows of each figure's kind: every figure names its
# case and shows its durations in one unit; figure3 draws a network's angles from its centre of
# inertia; the identification figure carries the rows' intervals; the pages' headings are short.

_UNITS = re.compile(r"(?<![\w./^-])(s|ms|µs|us)(?![\w/])")


def _texts(fig) -> list[str]:
    """The figure's title(s), every axes' title and axis labels, and any text drawn in the axes."""
    texts = [t.get_text() for t in fig.texts]
    for ax in fig.axes:
        texts += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel(), *(t.get_text() for t in ax.texts)]
    return [t for t in texts if t]


def _accuracy(case: str, quantity: str, values: np.ndarray, seed: int = 0) -> dict:
    """An accuracy row of a trained adapter whose best and worst trajectory are `values` (n_t, n)."""
    return {"suite": "accuracy", "case": case, "solver": "toy-pinn", "config": "default", "variant": "",
            "seed": seed, "trains": True, "status": "ok", "quantity": quantity, "against": "reference",
            "rel_l2": 1e-3, "max_abs": 1e-3, "worst_trajectory_rel_l2": 1e-3, "best_P1": 0.1, "worst_P1": 0.2,
            **{f"{which}_{kind}": values.tolist() for which in ("best", "worst") for kind in ("pred", "ref")}}


def _figure3_rows(case: str) -> list[dict]:
    """Angles that drift together by 1.6 rad/s (to 16 rad at 10 s) around small swings."""
    from systems.cases import CASES, standard_grid

    t, _ = standard_grid(CASES[case])
    n = CASES[case].n
    delta = 1.6 * t[:, None] + 0.1 * np.sin(t[:, None] + np.arange(n))
    return [_accuracy(case, "delta", delta), _accuracy(case, "omega", np.gradient(delta, t, axis=0))]


def _identification_rows() -> list[dict]:
    """SMIB identification rows: m's estimate off the truth outside its interval, d's inside."""
    base = {"suite": "identification", "case": "smib-identification", "solver": "scipy-odeint", "config": "tight",
            "variant": "", "seed": -1, "trains": False, "status": "ok", "noise": 0.0, "data": "reference"}
    return [{**base, "pair": 0, "m_true": 0.25, "m_est": 0.26, "m_ci95_low": 0.255, "m_ci95_high": 0.265,
             "m_rel_error": 0.04, "d_true": 0.15, "d_est": 0.151, "d_ci95_low": 0.144, "d_ci95_high": 0.159,
             "d_rel_error": 1 / 150}]


def _cct_rows() -> list[dict]:
    """A wscc9 fault's cct row (an adapter 60 us off a 183 ms CCT), with its trajectories."""
    t = np.linspace(0.0, 3.0, 31)
    traj = np.stack([np.outer(np.sin(t), [1.0, -0.5, 0.2]), np.outer(t, [2.0, -1.0, 0.5])])
    return [{"suite": "cct", "case": "wscc9-bus8-line8-9", "solver": "numba-rk", "config": "rk4", "variant": "",
             "seed": -1, "trains": False, "status": "ok", "reference_cct_s": 0.183, "cct_error_s": 6e-5,
             "bracket_s": 1e-3, "cct_s": 0.18306, "stable_s": 0.18256, "unstable_s": 0.18356, "method": "bisection", "note": "", "solves": 10, "trajectories": 11,
             "median_s": 1e-3, "q25_s": 1e-3, "q75_s": 1e-3, "repeats": 5, "traj_t": t.tolist(), "traj_t_c": [0.173, 0.193], "traj_ref": traj.tolist(),
             "traj_pred": traj.tolist()}]


def _verdict_rows() -> list[dict]:
    return [{"suite": "verdict", "case": case, "solver": "toy-pinn", "config": "default", "variant": "", "seed": 0,
             "trains": True, "status": "ok", "query": "grid 100x201", "kind": "grid", "label": "PINN faster",
             "pinn_seed": 0, "ratio": 3.0, "ratio_low": 2.0, "ratio_high": 4.0, "pinn_rel_l2_delta": 1e-3,
             "pinn_rel_l2_omega": 1e-3} for case in ("smib-inference", "wscc9")]


def _scaling_frame() -> pd.DataFrame:
    n = np.array([3, 10, 39])
    return pd.DataFrame({"case": ["wscc9", "case10", "ieee39"], "N": n, "label": "numba-rk [rk4]", "trains": False,
                         "prep_s": 1e-3 * n, "grid_s": 2e-3 * n, "point_s": 1e-4 * n, "peak_rss_mib": 100.0 * n,
                         "rel_l2": 1e-6})


def _figure(kind: str):
    """(figure of `kind` from its synthetic rows, the case(s) its title must name)."""
    from harness.report.frames import suite_frames
    from harness.report.labels import Labels
    from harness.report.plots import PLOTS, SCALING_PLOTS, VERDICT_PLOTS
    from tests.test_verdict import _rows as latency_rows

    rows = {"figure3": _figure3_rows("wscc9"), "identification": _identification_rows(), "cct": _cct_rows(),
            "verdicts": _verdict_rows()}.get(kind, latency_rows())
    frames = {"scaling_frame": _scaling_frame()} if kind in SCALING_PLOTS else suite_frames(rows)
    build = {**PLOTS, **SCALING_PLOTS, **VERDICT_PLOTS}[kind]
    scaling = ["wscc9", "case10", "ieee39"]
    cases = {"scaling_cost": scaling, "scaling_accuracy": scaling, "verdicts": ["smib-inference", "wscc9"]}
    return build(frames, Labels(frames)), cases.get(kind, [rows[0]["case"]])


FIGURES = ("latency_t1", "work_precision", "crossover", "figure3", "identification", "cct", "verdicts",
           "scaling_cost", "scaling_accuracy")


@pytest.mark.parametrize("kind", FIGURES)
def test_every_figure_names_its_case_in_its_title_and_shows_its_durations_in_one_unit(kind):
    """The case(s) of its rows in its title (the suptitle or an axes' title); one unit of time in its
    titles, labels and annotations (simulated time, t1, apart: s), written µs, never "us"."""
    import matplotlib.pyplot as plt

    fig, cases = _figure(kind)
    assert fig is not None
    texts = _texts(fig)
    titles = [t.get_text() for t in fig.texts] + [ax.get_title() for ax in fig.axes]
    assert any(all(case in title for case in cases) for title in titles), titles
    units = {unit for text in texts if "simulated" not in text for unit in _UNITS.findall(text)}
    assert len(units) <= 1 and "us" not in units, (units, texts)
    plt.close(fig)


def test_time_unit_is_chosen_from_the_data():
    from harness.report.plot_style import time_unit

    assert time_unit([2e-6, 3e-5, 5e-5]).name == "µs"
    assert time_unit([2e-3, np.nan, 0.0]) == ("ms", 1e3)
    assert time_unit([0.5, 3.0, 20.0]).name == "s"
    assert time_unit([]).name == "s"


@pytest.mark.parametrize("case", ["wscc9", "smib-inference"])
def test_figure3_draws_a_network_s_angles_from_its_centre_of_inertia_and_the_smib_s_as_they_are(case):
    """The stored angles drift to 16 rad: a network's panels show delta - delta_COI (within the
    swings' 0.2 rad); the SMIB's, against its infinite bus, the angles as stored."""
    import matplotlib.pyplot as plt

    from harness.report.frames import suite_frames
    from harness.report.labels import Labels
    from harness.report.plots import figure3
    from systems.cases import CASES
    from systems.model import relative_angles

    rows = _figure3_rows(case)
    frames = suite_frames(rows)
    fig = figure3(frames, Labels(frames))
    stored = np.asarray(rows[0]["best_ref"])
    drawn = np.column_stack([line.get_ydata() for line in fig.axes[0].lines])[:, :CASES[case].n]
    np.testing.assert_allclose(drawn, relative_angles(CASES[case], stored))
    if CASES[case].has_infinite_bus:
        np.testing.assert_allclose(drawn, stored)
    else:
        assert np.abs(drawn).max() < 0.25 and np.abs(stored).max() > 10
        assert "delta_COI" in fig.axes[0].get_ylabel()
    plt.close(fig)


def test_the_identification_figure_draws_each_rows_interval_of_its_error():
    """m: estimate 0.26 in [0.255, 0.265], truth 0.25 outside: error 4 % in [2 %, 6 %]; d: truth
    0.15 inside [0.144, 0.159]: the error's interval reaches down to 0 (a bar open below the point:
    from its 0.67 %) and up to 6 %."""
    import matplotlib.pyplot as plt

    from harness.report.identification_plot import error_interval

    fig, _ = _figure("identification")
    for ax, (low, high) in zip(fig.axes[:2], ((0.02, 0.06), (1 / 150, 0.06))):
        (container,) = ax.containers
        (segment,) = container.lines[2][0].get_segments()
        np.testing.assert_allclose(segment[:, 1], [low, high], rtol=1e-6)
    row = pd.Series(_identification_rows()[0])
    assert error_interval(row, "m") == pytest.approx((0.02, 0.06))
    assert np.isnan(error_interval(row.drop("m_ci95_low"), "m")).all()
    assert "95 % interval" in fig.texts[0].get_text()
    plt.close(fig)


def test_the_results_pages_have_short_headings_and_say_the_rest_below_them(tmp_path):
    """Headings of a few words; what a table holds in the paragraph under its heading."""
    from harness.report.markdown import LADDER_ABOUT
    from harness.report.pages import write_pages
    from tests.test_verdict import _rows as latency_rows

    rows = latency_rows() + _cct_rows() + _verdict_rows()
    results, pages = tmp_path / "results", tmp_path / "pages"
    write_report(rows, results, {"threads": 2}, plots=False)
    text = "\n".join(page.read_text() for page in write_pages(rows, {"threads": 2}, pages, results))
    headings = [line.lstrip("#").strip() for line in text.splitlines() if line.startswith("#")]
    assert "Accuracy" in headings and "Critical clearing time" in headings
    long = [heading for heading in headings if len(heading.split()) > 6 or len(heading) > 45]
    assert not long, long
    assert LADDER_ABOUT in text and "median of repeats ± half the interquartile range" in text
