"""A case from a file (systems.case_file): pandapower JSON, MATPOWER .m and .mat give the same case
as the scaling family's rule on the same net; impedance elements are the branches they are; machine
data from a CSV; every bad file or row is one line naming it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from systems.case_file import case_from_file, file_cases, load_net
from systems.family import family_model
from systems.faults import Contingency
from systems.network import T_FINAL, network_case


def case9():
    import pandapower.networks as pn

    return pn.case9()


def write_json(net, path: Path) -> Path:
    import pandapower as pp

    pp.to_json(net, str(path))
    return path


def write_mat(net, path: Path) -> Path:
    from pandapower.converter.matpower.to_mpc import to_mpc

    to_mpc(net, str(path), init="flat")
    return path


def write_m(net, path: Path) -> Path:
    """A MATPOWER version 2 .m file of `net` (pandapower writes .mat only)."""
    from pandapower.converter.matpower.to_mpc import to_mpc

    mpc = to_mpc(net, init="flat")["mpc"]
    lines = [f"function mpc = {path.stem}", "mpc.version = '2';", f"mpc.baseMVA = {float(mpc['baseMVA'])!r};"]
    for key, columns in (("bus", 13), ("gen", 10), ("branch", 13)):  # MATPOWER's power-flow columns
        rows = np.atleast_2d(np.asarray(mpc[key], float))[:, :columns]
        lines += [f"mpc.{key} = ["] + ["\t" + "\t".join(repr(float(x)) for x in row) + ";" for row in rows] + ["];"]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


WRITERS = {".json": write_json, ".m": write_m, ".mat": write_mat}


@pytest.mark.parametrize("suffix", list(WRITERS))
def test_a_file_gives_the_familys_case_of_its_net(tmp_path, suffix):
    path = WRITERS[suffix](case9(), tmp_path / f"grid9{suffix}")
    case = case_from_file(path)
    expected = network_case("grid9", family_model(case9(), 60.0), t_final=T_FINAL)
    assert case.name == "grid9" and case.n == 3 and case.network is not None
    for key in ("m", "d", "E", "delta0", "p_m", "G", "B"):
        np.testing.assert_allclose(getattr(case, key), getattr(expected, key), rtol=1e-9, atol=1e-12, err_msg=key)
    assert case.p_m[0] == max(case.p_m)  # generator 1: the largest operating P


def test_a_name_and_fault_cases(tmp_path):
    path = write_json(case9(), tmp_path / "grid9.json")
    step, fault = file_cases(path, name="mine", faults=(Contingency("bus8-line8-9", 8, (8, 9)),))
    assert step.name == "mine" and fault.name == "mine-bus8-line8-9"
    assert fault.fault is not None and fault.delta0 == step.delta0
    assert fault.source.endswith("; fault: bus8-line8-9 (given with the file)")


def _with_impedance(asymmetric: bool = False):
    """case9 with line 4 (buses 5-6) once as a line without charging, once as the impedance of the
    same series r + jx (p.u. on sn_mva = 50 MVA, not the system's 100)."""
    import pandapower as pp

    as_line, as_impedance = case9(), case9()
    as_line.line.at[4, "c_nf_per_km"] = 0.0
    row = as_line.line.loc[4]
    z_base = as_line.bus.at[row.from_bus, "vn_kv"] ** 2 / 50.0
    r, x = row.r_ohm_per_km * row.length_km / z_base, row.x_ohm_per_km * row.length_km / z_base
    as_impedance.line.at[4, "in_service"] = False
    pp.create_impedance(as_impedance, row.from_bus, row.to_bus, rft_pu=r, xft_pu=x, sn_mva=50.0,
                        rtf_pu=r, xtf_pu=x * 1.5 if asymmetric else x, name="z5-6")
    return as_line, as_impedance


def test_an_impedance_is_the_series_branch_it_stands_for(tmp_path):
    as_line, as_impedance = _with_impedance()
    a = case_from_file(write_json(as_line, tmp_path / "line.json"))
    b = case_from_file(write_json(as_impedance, tmp_path / "impedance.json"))
    for key in ("G", "B", "p_m", "E", "delta0"):
        np.testing.assert_allclose(getattr(b, key), getattr(a, key), rtol=0, atol=1e-12, err_msg=key)


def test_an_asymmetric_impedance_is_refused_by_name(tmp_path):
    path = write_json(_with_impedance(asymmetric=True)[1], tmp_path / "asym.json")
    with pytest.raises(ValueError, match=r"asym\.json: net: impedance 0 \('z5-6'\) is asymmetric") as err:
        case_from_file(path)
    assert "\n" not in str(err.value)


def write_csv(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_machine_data_from_a_csv(tmp_path):
    net_path = write_json(case9(), tmp_path / "grid9.json")
    rule = write_csv(tmp_path / "rule.csv", "bus,H,xd_prime,D\n1,4,0.3,4\n2,4,0.3,4\n3,4,0.3,4\n")
    same = case_from_file(net_path, machines=rule)
    expected = case_from_file(net_path)
    for key in ("m", "d", "E", "G", "B", "p_m"):
        np.testing.assert_allclose(getattr(same, key), getattr(expected, key), rtol=1e-12, err_msg=key)
    heavy = case_from_file(net_path, machines=write_csv(tmp_path / "h.csv", "bus,H,xd_prime,D\n3,8,0.3,2\n2,4,0.3,4\n"
                                                                              "1,4,0.3,4\n"))
    k = next(i for i, x in enumerate(expected.p_m) if np.isclose(x, 0.85))  # the gen at bus 3: 85 MW
    assert heavy.m[k] == pytest.approx(2 * expected.m[k]) and heavy.d[k] == pytest.approx(expected.d[k] / 2)


GOOD = "bus,H,xd_prime,D\n1,4,0.3,4\n2,4,0.3,4\n3,4,0.3,4\n"


@pytest.mark.parametrize(("text", "message"), [
    ("bus,H,xd\n1,4,0.3\n", r"rows\.csv:1: the header must be bus,H,xd_prime,D"),
    (GOOD.replace("2,4,0.3,4", "2,4,0.3"), r"rows\.csv:3: 3 fields, missing column"),
    (GOOD.replace("2,4,0.3,4", "2,4,0.3,4,9"), r"rows\.csv:3: 5 fields, extra column"),
    (GOOD.replace("2,4,0.3,4", "99,4,0.3,4"), r"rows\.csv:3: bus 99: the net has no such bus"),
    (GOOD.replace("2,4,0.3,4", "5,4,0.3,4"), r"rows\.csv:3: bus 5 has no in-service generator"),
    (GOOD.replace("2,4,0.3,4", "2,-1,0.3,4"), r"rows\.csv:3: H must be > 0, got '-1'"),
    (GOOD.replace("2,4,0.3,4", "2,4,0,4"), r"rows\.csv:3: xd_prime must be > 0, got '0'"),
    (GOOD.replace("2,4,0.3,4", "2,4,x,4"), r"rows\.csv:3: xd_prime 'x' is not a number"),
    (GOOD.replace("2,4,0.3,4", "1,4,0.3,4"), r"rows\.csv:3: bus 1 is given twice"),
    (GOOD.replace("3,4,0.3,4\n", ""), r"rows\.csv: bus 3 has a generator but no row"),
])
def test_a_bad_machine_row_is_one_line_naming_the_file_line_and_field(tmp_path, text, message):
    net_path = write_json(case9(), tmp_path / "grid9.json")
    with pytest.raises(ValueError, match=message) as err:
        case_from_file(net_path, machines=write_csv(tmp_path / "rows.csv", text))
    assert "\n" not in str(err.value)


def _no_generators():
    net = case9()
    net.gen["in_service"] = False
    net.ext_grid["in_service"] = False
    return net


def _overloaded():
    net = case9()
    net.load["p_mw"] *= 40
    return net


@pytest.mark.parametrize(("make", "name", "message"), [
    (None, "absent.json", r"absent\.json: no such file"),
    (None, "grid.raw", r"grid\.raw: unknown suffix '\.raw'; a case file is \.json, \.m, \.mat"),
    ("garbage", "bad.json", r"bad\.json: unreadable as \.json"),
    ("garbage", "bad.mat", r"bad\.mat: unreadable as \.mat"),
    (_no_generators, "none.json", r"none\.json: the net has no in-service generator"),
    (_overloaded, "heavy.json", r"heavy\.json: the power flow does not converge"),
])
def test_a_bad_file_is_one_line_naming_it(tmp_path, make, name, message):
    path = tmp_path / name
    if make == "garbage":
        path.write_text("{not a net", encoding="utf-8")
    elif make is not None:
        write_json(make(), path)
    with pytest.raises(ValueError, match=message) as err:
        case_from_file(path)
    assert "\n" not in str(err.value)


def test_a_bad_contingency_is_one_line_naming_it(tmp_path):
    path = write_json(case9(), tmp_path / "grid9.json")
    with pytest.raises(ValueError, match=r"grid9\.json: Contingency 'bus4-line4-6': net has 0 in-service line"):
        file_cases(path, faults=(Contingency("bus4-line4-6", 4, (4, 6)),))


def test_buses_without_integer_names_are_numbered_by_index(tmp_path):
    net = case9()
    net.bus["name"] = [f"B{k}" for k in range(len(net.bus))]
    loaded = load_net(write_json(net, tmp_path / "named.json"))
    assert loaded.bus.name.tolist() == list(range(9))
