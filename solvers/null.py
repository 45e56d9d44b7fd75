"""The do-nothing adapter: what `solve` costs when the adapter itself does no work.

Used only by the latency suite (its "interface" rows) and the tests; not in `solvers.SOLVERS`.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from solvers.base import AbstractSolver, Estimate
from systems.cases import Observations

__all__ = ["NullSolver"]


class NullSolver(AbstractSolver):
    """Returns zeros of the right shape, preallocated per shape, so its `solve` times the
    validation, conversions and returned record of the interface and nothing else."""

    name: ClassVar[str] = "interface-overhead"
    does_work: ClassVar[bool] = False

    def _fit(self) -> None:
        self._zeros: dict[tuple[int, ...], np.ndarray] = {}

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        shape = (P1.shape[0], t.shape[0], self.case.n)
        zeros = self._zeros.get(shape)
        if zeros is None:
            zeros = self._zeros[shape] = np.zeros(shape)
        return zeros, zeros

    def _solve_points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        shape = (t.shape[0], self.case.n)
        zeros = self._zeros.get(shape)
        if zeros is None:
            zeros = self._zeros[shape] = np.zeros(shape)
        return zeros, zeros

    def _identify(self, obs: Observations) -> Estimate:
        raise NotImplementedError(f"{self.name} measures the interface only; it does not identify")
