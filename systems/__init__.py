"""The problem: cases, the swing model, network building, the tight reference.

Importing the package imports the modules that register network cases in `systems.cases.CASES`
(`register_case`); a case is built on first use, so these imports solve no power flow. `CASES`
lists cases in the order they were registered: the paper's networks, the scaling family, the fault cases
(`systems.faults.FAULT_CASES`), then the cases of other packages (`systems.case_plugins`).
"""

from systems import grids  # noqa: F401, I001 - its builders register themselves, first
from systems import family  # noqa: F401 - likewise
from systems import faults  # noqa: F401 - likewise: the fault cases, '<case>-<contingency>'
from systems.case_plugins import register_plugin_cases  # after the built-ins, which keep their names

register_plugin_cases()
