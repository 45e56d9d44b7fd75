"""Error measures: pure numpy functions of arrays, no state."""

from __future__ import annotations

import numpy as np

__all__ = ["max_abs", "rel_error", "rel_l2", "rel_l2_per_row"]


def rel_l2(pred: np.ndarray, ref: np.ndarray) -> float:
    """||pred - ref||_2 / ||ref||_2 over all entries (the paper's measure, over the whole grid)."""
    pred, ref = np.asarray(pred, float), np.asarray(ref, float)
    if pred.shape != ref.shape:
        raise ValueError(f"shapes differ: pred {pred.shape}, ref {ref.shape}")
    return float(np.linalg.norm(pred - ref) / np.linalg.norm(ref))


def rel_l2_per_row(pred: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Relative L2 of each row (one trajectory per row): shape (n_rows,)."""
    pred, ref = np.asarray(pred, float), np.asarray(ref, float)
    if pred.shape != ref.shape:
        raise ValueError(f"shapes differ: pred {pred.shape}, ref {ref.shape}")
    return np.linalg.norm(pred - ref, axis=-1) / np.linalg.norm(ref, axis=-1)


def max_abs(pred: np.ndarray, ref: np.ndarray) -> float:
    """max |pred - ref| over all entries, in the unit of the inputs."""
    pred, ref = np.asarray(pred, float), np.asarray(ref, float)
    if pred.shape != ref.shape:
        raise ValueError(f"shapes differ: pred {pred.shape}, ref {ref.shape}")
    return float(np.max(np.abs(pred - ref)))


def rel_error(estimate: float, truth: float) -> float:
    """|estimate - truth| / |truth| (a parameter's relative error)."""
    return float(abs(estimate - truth) / abs(truth))
