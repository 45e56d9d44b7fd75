"""Your own grid: a case from a network file, turned into a classical swing case by the scaling
family's code (`systems.family.family_model`).

Files: a pandapower JSON (`.json`, `pandapower.to_json`), a MATPOWER case (`.m`, read by
pandapower's `from_mpc` with the optional `matpowercaseframes`; `.mat`, a MATLAB file holding the
struct `mpc`). Every in-service gen and ext_grid is a machine, several at one bus merged into one
(`family.merge_machines`); generator 1 (machine 0, whose mechanical power steps to P1 = its
operating P +- 30 %) is the machine with the largest operating P; transformer phase shifts are set
to 0; horizon `network.T_FINAL` = 10 s. Machine data: the family's rule (H = 4 s, x'd = 0.3 p.u.
on each machine's rating max(sn_mva or P_max, |S_flow|, 10 MVA), d = 0.5 m), or a CSV of rows
`bus,H,xd_prime,D` (`read_machines`) on that same rating.

Buses are named by number: pandapower's `bus.name` where every bus has a distinct integer name
(a MATPOWER file's bus numbers), else the pandapower bus index (the names are then set to it). The
machine CSV's `bus` column and a contingency's buses (`systems.faults.Contingency`) use them.
Frequency: the JSON's `net.f_hz`; a MATPOWER file carries none, so `f_hz` (default 60 Hz).

Every refusal is one ValueError naming the file and what is wrong.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING

from systems.cases import Case
from systems.family import H_S, RATING_FLOOR_MVA, XD_PRIME, MachineData, family_model, machine_buses
from systems.faults import Contingency, fault_case, fault_networks
from systems.network import T_FINAL, ClassicalModel, network_case

if TYPE_CHECKING:  # annotations only: importing pandapower costs seconds
    from pandapower.auxiliary import pandapowerNet

__all__ = ["MACHINE_COLUMNS", "MATPOWER_F_HZ", "SUFFIXES", "case_from_file", "file_cases", "load_net",
           "read_machines"]

SUFFIXES = (".json", ".m", ".mat")
MACHINE_COLUMNS = ("bus", "H", "xd_prime", "D")
# A MATPOWER file states no frequency: the default (Hz) unless f_hz is given.
MATPOWER_F_HZ = 60.0


def load_net(path: str | Path, f_hz: float | None = None) -> pandapowerNet:
    """The pandapower net of the file `path` (`SUFFIXES`), its buses named by number (module
    docstring); f_hz (Hz) sets a MATPOWER file's frequency (default `MATPOWER_F_HZ`) and overrides
    a JSON's. ValueError naming the file if it is missing, of another suffix or unreadable."""
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise ValueError(f"{path}: unknown suffix {path.suffix!r}; a case file is {', '.join(SUFFIXES)}")
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    import pandapower as pp
    from pandapower.converter.matpower.from_mpc import from_mpc

    try:
        if path.suffix.lower() == ".json":
            net = pp.from_json(str(path))
        else:
            net = from_mpc(str(path), f_hz=MATPOWER_F_HZ if f_hz is None else f_hz)
    except NotImplementedError as exc:  # pandapower's word for matpowercaseframes missing
        raise ValueError(f"{path}: cannot read a .m file without matpowercaseframes ({exc})") from None
    except Exception as exc:  # noqa: BLE001 - any reader failure is an unreadable file, said in one line
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise ValueError(f"{path}: unreadable as {path.suffix} ({type(exc).__name__}: {first[:120]})") from None
    if not isinstance(net, pp.pandapowerNet) or "bus" not in net:
        raise ValueError(f"{path}: holds no pandapower net")
    if f_hz is not None:
        net.f_hz = float(f_hz)
    names = net.bus.name.tolist()
    if not all(isinstance(x, (int, float)) and float(x).is_integer() for x in names) \
            or len({int(x) for x in names}) != len(names):
        net.bus["name"] = net.bus.index.astype(int)
    else:
        net.bus["name"] = [int(x) for x in names]
    return net


def _number(path: Path, line: int, field: str, text: str) -> float:
    """Field `field` of line `line` as a positive finite float, or a ValueError naming them."""
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{path}:{line}: {field} {text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{path}:{line}: {field} must be > 0, got {text!r}")
    return value


def read_machines(path: str | Path, net: pandapowerNet) -> dict[int, MachineData]:
    """pandapower bus index -> `MachineData` from the CSV `path`: the header `bus,H,xd_prime,D`, then
    one row per machine bus (`bus` the bus number, module docstring; H s and xd_prime p.u. on the
    machine's rating, D p.u. power per p.u. speed deviation on that rating; each > 0). ValueError
    naming the file, line and field: missing or extra columns, an unknown bus, a bus with no
    in-service gen or ext_grid, a bus given twice, a value that is no positive number, or a
    machine bus the file leaves out."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the machine data ({type(exc).__name__}: {exc})") from None
    rows = [(k, row) for k, row in enumerate(csv.reader(text.splitlines()), start=1) if any(c.strip() for c in row)]
    if not rows or tuple(c.strip() for c in rows[0][1]) != MACHINE_COLUMNS:
        got = ",".join(rows[0][1]) if rows else "nothing"
        raise ValueError(f"{path}:{rows[0][0] if rows else 1}: the header must be {','.join(MACHINE_COLUMNS)}, "
                         f"got {got!r}")
    index = {int(name): int(idx) for idx, name in zip(net.bus.index, net.bus.name)}
    machines = {int(net.bus.at[b, "name"]): b for b in machine_buses(net)}
    found: dict[int, MachineData] = {}
    for line, row in rows[1:]:
        if len(row) != len(MACHINE_COLUMNS):
            what = "missing" if len(row) < len(MACHINE_COLUMNS) else "extra"
            raise ValueError(f"{path}:{line}: {len(row)} fields, {what} column(s): a row is {','.join(MACHINE_COLUMNS)}")
        try:
            bus = int(row[0].strip())
        except ValueError:
            raise ValueError(f"{path}:{line}: bus {row[0]!r} is not a bus number") from None
        if bus not in index:
            raise ValueError(f"{path}:{line}: bus {bus}: the net has no such bus")
        if bus not in machines:
            raise ValueError(f"{path}:{line}: bus {bus} has no in-service generator (gen or ext_grid)")
        if machines[bus] in found:
            raise ValueError(f"{path}:{line}: bus {bus} is given twice")
        found[machines[bus]] = MachineData(*(_number(path, line, field, value.strip())
                                             for field, value in zip(MACHINE_COLUMNS[1:], row[1:])))
    missing = sorted(bus for bus, idx in machines.items() if idx not in found)
    if missing:
        raise ValueError(f"{path}: bus {missing[0]} has a generator but no row"
                         + (f" (and {len(missing) - 1} more: {missing[1:]})" if len(missing) > 1 else ""))
    return found


def _model(path: Path, machines, f_hz: float | None) -> tuple[pandapowerNet, ClassicalModel]:
    """The net of `path` and its classical model; every ValueError names the file."""
    net = load_net(path, f_hz)
    if not machine_buses(net):
        raise ValueError(f"{path}: the net has no in-service generator (gen or ext_grid)")
    data = None if machines is None else read_machines(machines, net)
    from pandapower.powerflow import LoadflowNotConverged

    try:
        return net, family_model(net, float(net.f_hz), data)
    except LoadflowNotConverged:
        raise ValueError(f"{path}: the power flow does not converge") from None
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def _source(path: Path, machines, f_hz: float) -> str:
    data = (f"machines: every gen and ext_grid, one per bus, H, x'd, D from {Path(machines).name} on rating"
            if machines is not None else
            f"machines: every gen and ext_grid, one per bus, H = {H_S:g} s, x'd = {XD_PRIME:g} p.u. on rating")
    return (f"network: {path.name}; {data} max(sn_mva or P_max, |S_flow|, {RATING_FLOOR_MVA:g} MVA) "
            f"(systems.family's rule); {f_hz:g} Hz; generator 1 = the largest P; phase shifts set to 0"
            + ("; damping d = 0.5 m (ours)" if machines is None else ""))


def file_cases(path: str | Path, machines: str | Path | None = None, name: str | None = None,
               faults: tuple[Contingency, ...] = (), f_hz: float | None = None) -> list[Case]:
    """The step case of the file `path` (`case_from_file`), then one fault case per contingency
    of `faults` on it (`systems.faults.fault_case`, named '<name>-<contingency>'), all from one power
    flow. ValueError naming the file, or the contingency (`faults.fault_networks`' checks: the bus and
    the line exist, the line touches the bus, opening it does not split the network)."""
    path = Path(path)
    net, model = _model(path, machines, f_hz)
    case = network_case(name or path.stem, model, t_final=T_FINAL, source=_source(path, machines, model.f_hz))
    out = [case]
    for contingency in faults:
        try:
            faulted = fault_case(case, fault_networks(net, model, contingency))
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None
        out.append(dataclasses.replace(faulted, source=f"{case.source}; fault: {contingency.name} (given with the file)"))
    return out


def case_from_file(path: str | Path, machines: str | Path | None = None, name: str | None = None,
                   f_hz: float | None = None) -> Case:
    """The classical swing `Case` of the network file `path` (module docstring), named `name` (default
    the file's stem); machines: None (the family's rule) or a CSV (`read_machines`)."""
    return file_cases(path, machines, name, (), f_hz)[0]
