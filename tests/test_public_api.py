"""Every public name a subpackage lists resolves, and importing a subpackage stays cheap."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

pytestmark = pytest.mark.base  # runs in the base-install job too

PACKAGES = [
    "qdcnn.data",
    "qdcnn.vision",
    "qdcnn.quantum",
    "qdcnn.models",
    "qdcnn.direction",
    "qdcnn.runtime",
    "qdcnn.experiments",
]
NEEDS = {"qdcnn.models": "torch"}


@pytest.mark.parametrize("package", PACKAGES)
def test_every_listed_name_resolves(package: str) -> None:
    module = importlib.import_module(package)
    assert module.__all__ == sorted(module.__all__) and module.__all__
    for name in module.__all__:
        if package in NEEDS and name not in (
            "ARCHS",
            "CNNDirectionClassifier",
            "inference_fps",
            "NETWORKS",
            "build_network",
            "register_network",
        ):
            pytest.importorskip(NEEDS[package])
        assert getattr(module, name) is not None, name
    with pytest.raises(AttributeError, match="has no attribute 'nothing_here'"):
        module.nothing_here  # noqa: B018


def test_importing_the_subpackages_loads_no_heavy_extra() -> None:
    code = "import qdcnn.data, qdcnn.vision, qdcnn.quantum, qdcnn.models, qdcnn.experiments, sys; "
    code += (
        "print(sorted(m for m in ('torch', 'qiskit', 'qiskit_aer', 'dask') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
