"""Moved to :mod:`qdcnn.batch`; this name stays for existing imports."""

from qdcnn.batch import Failure, Outcome, run_batch

__all__ = ["Failure", "Outcome", "run_batch"]
