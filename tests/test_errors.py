"""Errors pickle with their message and attributes (they travel to and from workers)."""

from __future__ import annotations

import pickle

from qdcnn.data.recording import RowError
from qdcnn.errors import InputError, OptionConflict, ParameterError


def test_errors_survive_pickling_with_their_attributes() -> None:
    row = pickle.loads(pickle.dumps(RowError("log.csv", 3, 1, "steering 'abc' is not a number")))
    assert isinstance(row, RowError) and (row.row, row.position) == (3, 1)
    assert str(row) == "log.csv:row 3: steering 'abc' is not a number"
    error = pickle.loads(pickle.dumps(InputError("a.png", "empty file (0 bytes)")))
    assert (error.source, error.reason, str(error)) == ("a.png", "empty file (0 bytes)", str(error))
    param = pickle.loads(pickle.dumps(ParameterError("seed", -1, "an integer >= 0")))
    assert param.name == "seed" and str(param) == "seed=-1 is invalid: an integer >= 0"
    conflict = pickle.loads(pickle.dumps(OptionConflict("--a", "--b", "why")))
    assert conflict.options == ("--a", "--b")
