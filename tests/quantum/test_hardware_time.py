"""The labelled hardware-time estimate reproduces the paper's figure from its assumptions."""

from __future__ import annotations

import pytest

from qdcnn.quantum.hardware_time import PAPER_TIME_S, PROFILES, estimate_time


def test_reproduces_paper_time() -> None:
    est = estimate_time("paper-photonic")
    assert est.seconds == pytest.approx(PAPER_TIME_S, rel=1e-12)
    assert est.elements == 474 * 474 == 224_676
    assert est.runs == 1000 and est.gates == 2
    assert est.kind == "estimate"
    assert PROFILES["paper-photonic"].gate_time_s == pytest.approx(10.983e-12, rel=1e-4)


def test_round_10ps_gives_the_undropped_digit() -> None:
    assert estimate_time("photonic-10ps").seconds == pytest.approx(0.00449352, rel=1e-12)


def test_real_devices_count_readout_and_reset() -> None:
    sc = estimate_time("superconducting-ibm-heron")
    n = 224_676 * 1000
    assert sc.seconds == pytest.approx(n * (2 * 32e-9 + 1560e-9 + 1708e-9))
    ion = estimate_time("trapped-ion-ionq-harmony", elements=6241, runs=1024)
    assert ion.seconds == pytest.approx(6241 * 1024 * (2 * 10e-6 + 100e-6 + 25e-6))
    assert ion.to_dict()["kind"] == "estimate"
