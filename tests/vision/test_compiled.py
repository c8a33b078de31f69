"""The switch between compiled kernels and NumPy paths."""

from __future__ import annotations

import builtins
from typing import Any

import pytest

from qdcnn.vision import compiled as compiled_module
from qdcnn.vision.compiled import KERNELS_VARIABLE, compiled


def test_numpy_selects_no_kernels(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(KERNELS_VARIABLE, "numpy")
    assert compiled("block_kernels") is None
    assert compiled("removal_kernels") is None


def _kernels_when_numba_raises(monkeypatch: pytest.MonkeyPatch, error: ImportError) -> object:
    """``compiled("removal_kernels")`` when ``import numba`` raises ``error``."""
    real_import = builtins.__import__

    def failing(name: str, *args: Any, **kwargs: Any) -> Any:
        if name == "numba" or name.startswith("numba."):
            raise error
        return real_import(name, *args, **kwargs)

    monkeypatch.delenv(KERNELS_VARIABLE, raising=False)
    monkeypatch.setattr(builtins, "__import__", failing)
    monkeypatch.delitem(__import__("sys").modules, "qdcnn.vision.removal_kernels", raising=False)
    compiled_module._imported.cache_clear()
    try:
        return compiled("removal_kernels")
    finally:
        compiled_module._imported.cache_clear()


def test_a_missing_numba_gives_the_numpy_paths(monkeypatch: pytest.MonkeyPatch) -> None:
    missing = ModuleNotFoundError("No module named 'numba'", name="numba")
    assert _kernels_when_numba_raises(monkeypatch, missing) is None


def test_another_missing_module_is_not_hidden(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(KERNELS_VARIABLE, raising=False)
    compiled_module._imported.cache_clear()
    try:
        with pytest.raises(ModuleNotFoundError, match="no_such_kernels"):
            compiled("no_such_kernels")
    finally:
        compiled_module._imported.cache_clear()


def test_numba_refusing_this_numpy_gives_the_numpy_paths(monkeypatch: pytest.MonkeyPatch) -> None:
    refusal = ImportError("Numba needs NumPy 2.2 or less")  # as numba/__init__ says it
    assert _kernels_when_numba_raises(monkeypatch, refusal) is None


def test_another_setting_is_named_in_the_error(monkeypatch: pytest.MonkeyPatch) -> None:
    from qdcnn.errors import ParameterError

    monkeypatch.setenv(KERNELS_VARIABLE, "off")
    with pytest.raises(ParameterError) as err:
        compiled("block_kernels")
    assert str(err.value) == "QDCNN_KERNELS='off' is invalid: 'numba' or 'numpy'"


@pytest.mark.parametrize("mapping", ["os.environ", "a plain mapping"])
@pytest.mark.parametrize("value", [None, "numpy", "numba"])
def test_the_setting_is_read_on_every_call(
    monkeypatch: pytest.MonkeyPatch, mapping: str, value: str | None
) -> None:
    """The choice follows the variable as it is now, whether read from CPython's mapping
    behind ``os.environ`` or (where an ``os.environ`` has none) through ``get``."""
    import os

    if mapping == "a plain mapping":
        monkeypatch.setattr(os, "environ", dict(os.environ))
    if value is None:
        monkeypatch.delitem(os.environ, KERNELS_VARIABLE, raising=False)
    else:
        monkeypatch.setitem(os.environ, KERNELS_VARIABLE, value)
    assert compiled_module._environment_choice() == (value or "numba")
    assert (compiled("block_kernels") is None) is (value == "numpy")
