"""The step-claim table and the one-step table, from synthetic rows and a synthetic CSV (no
solver runs)."""

from __future__ import annotations

import pandas as pd

from harness.report.files import write_report
from harness.report.frames import suite_frames
from harness.report.step_claim import NONE, one_step_table, step_claim_markdown, step_claim_table

_BASE = {"suite": "work_precision", "case": "wscc9", "variant": "", "threads": 2, "status": "ok",
         "q25_s": 0.9, "q75_s": 1.1, "repeats": 3, "point_q25_s": 0.009, "point_q75_s": 0.011, "point_repeats": 3}
_PINN = {**_BASE, "solver": "step-pinn", "config": "default", "seed": 0, "trains": True}
_RK4 = {**_BASE, "solver": "numba-rk", "config": "rk4", "seed": -1, "trains": False}


def _point(spec: dict, option: str, step_s: float, coi: float, grid_s: float) -> dict:
    """A work-precision row at step `step_s` (s, under `option`) with COI rel. L2 `coi` and grid
    query time `grid_s` (s); the single point takes a hundredth of it."""
    return {**spec, option: step_s, "setting": f"{option}={step_s:g}", "rel_l2_delta": coi, "rel_l2_delta_coi": coi,
            "rel_l2_omega": 2 * coi, "median_s": grid_s, "point_median_s": grid_s / 100}


def _rows(pinn: bool = True) -> list[dict]:
    """pinnsim-like steps h (none qualifies at 1e-3 but 0.025, with a finer step that is worse), rk4
    steps dt (0.05 and finer qualify), and a tolerance sweep that must not count as a step sweep."""
    rows = [_point(_RK4, "dt", 0.1, 2e-3, 0.01), _point(_RK4, "dt", 0.05, 1e-4, 0.02),
            _point(_RK4, "dt", 0.02, 4e-6, 0.05),
            {**_BASE, "solver": "numba-rk", "config": "default", "seed": -1, "trains": False, "rtol": 1e-3,
             "setting": "rtol=0.001", "rel_l2_delta": 1e-4, "rel_l2_delta_coi": 1e-4, "rel_l2_omega": 1e-4,
             "median_s": 0.01, "point_median_s": 1e-4}]
    if pinn:
        rows += [_point(_PINN, "h", 0.25, 7e-3, 1.7), _point(_PINN, "h", 0.1, 1.5e-3, 2.2),
                 _point(_PINN, "h", 0.025, 2.4e-4, 5.0), _point(_PINN, "h", 0.01, 3.9e-4, 18.0)]
    return rows


def _cell(table: pd.DataFrame, solver: str, column: str) -> str:
    return table.loc[table["solver"].str.startswith(solver), column].item()


def test_the_largest_qualifying_step_is_chosen_with_the_times_of_its_row():
    table = step_claim_table(suite_frames(_rows()))
    step = "largest step at COI rel. L2 <= 0.001 (s)"
    assert list(table["solver"]) == ["numba-rk [rk4]", "step-pinn [default]"]  # no tolerance sweep
    assert _cell(table, "step-pinn", step) == "0.025" and _cell(table, "numba-rk", step) == "0.05"
    assert _cell(table, "step-pinn", "COI rel. L2") == "0.00024"
    assert _cell(table, "step-pinn", "grid 100 x 201 (ms)").startswith("5e+03 ")
    assert _cell(table, "numba-rk", "single point t1 = 10 s (ms)").startswith("0.2 ")


def test_no_qualifying_step_says_none_with_the_finest_steps_error():
    table = step_claim_table(suite_frames(_rows()), threshold=1e-5)
    step = "largest step at COI rel. L2 <= 1e-05 (s)"
    assert _cell(table, "step-pinn", step) == f"{NONE} (finest 0.01 s)"
    assert _cell(table, "step-pinn", "COI rel. L2") == "0.00039"
    assert _cell(table, "step-pinn", "grid 100 x 201 (ms)") == "n/a"
    assert _cell(table, "numba-rk", step) == "0.02"


def test_the_section_is_absent_without_a_trained_step_sweep(tmp_path):
    assert step_claim_table(suite_frames(_rows(pinn=False))).empty
    assert step_claim_markdown(suite_frames(_rows(pinn=False)), tmp_path) == ""
    assert "Step claim" not in write_report(_rows(pinn=False), tmp_path, {}, plots=False)
    assert "## Step claim" in write_report(_rows(), tmp_path / "with", {}, plots=False)


def test_the_one_step_table_is_rendered_from_the_csv_in_the_folder(tmp_path):
    pd.DataFrame({"t_from_s": [0.0, 0.05], "t_to_s": [0.05, 0.1], "delta_max_rad": [1.4e-4, 7.5e-4],
                  "omega_p99_rad_s": [2.7e-3, 3.8e-3]}).to_csv(tmp_path / "component_error.csv", index=False)
    table = one_step_table(tmp_path / "component_error.csv")
    assert list(table.columns) == ["t (s)", "delta max (rad)", "omega p99 (rad/s)"]
    assert list(table["t (s)"]) == ["0 - 0.05", "0.05 - 0.1"] and table["delta max (rad)"].iloc[1] == "0.00075"
    markdown = step_claim_markdown(suite_frames(_rows(pinn=False)), tmp_path)
    assert "one-step error" in markdown and "Largest step" not in markdown


def test_the_results_pages_have_a_step_claim_page_linked_from_the_index(tmp_path):
    from harness.report.pages import write_pages

    results, pages = tmp_path / "results", tmp_path / "pages"
    write_report(_rows(), results, {}, plots=False)
    written = {path.name: path.read_text() for path in write_pages(_rows(), {}, pages, results)}
    assert "# Results: step claim" in written["step-claim.md"]
    assert "[Step claim](step-claim.md)" in written["index.md"]
    bare = {path.name for path in write_pages(_rows(pinn=False), {}, pages, results)}
    assert "step-claim.md" not in bare and not (pages / "step-claim.md").exists()
