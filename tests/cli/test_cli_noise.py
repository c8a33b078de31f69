"""``noise-sweep`` and ``circuit`` commands, registered on a throwaway Typer app as cli.py does."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from qdcnn.cli.noise import circuit_cmd, noise_sweep_cmd
from qdcnn.data.images import write_image, write_mask
from qdcnn.errors import ParameterError
from qdcnn.experiments.circuit import parse_angle
from qdcnn.experiments.noise import synthetic_shadow_set
from qdcnn.quantum.circuits import vqc_circuit
from qdcnn.quantum.simulator import probabilities

app = typer.Typer(pretty_exceptions_enable=False)
app.command("noise-sweep")(noise_sweep_cmd)
app.command("circuit")(circuit_cmd)
runner = CliRunner()


def json_lines(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


@pytest.fixture(autouse=True)
def _cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))


# ---------------------------------------------------------------- circuit


def test_parse_angle() -> None:
    assert parse_angle("pi/2", "a") == np.pi / 2
    assert parse_angle("-3pi/4", "a") == -3 * np.pi / 4
    assert parse_angle("2*pi", "a") == 2 * np.pi
    assert parse_angle("0.25", "a") == 0.25
    for bad in ("abc", "pi/0", "inf"):
        with pytest.raises(ParameterError, match=f"a={bad!r} is invalid"):
            parse_angle(bad, "a")


def test_circuit_uu_exact_and_noisy() -> None:
    res = runner.invoke(app, ["circuit", "uu", "--theta-c", "pi/2", "--theta-x", "0.3", "--json"])
    assert res.exit_code == 0, res.output
    (obj,) = json_lines(res.stdout)
    ideal = np.cos((np.pi / 2 - 0.3) / 2) ** 2
    np.testing.assert_allclose(obj["probabilities"], [ideal, 1 - ideal], atol=1e-12)
    assert obj["circuit"] == "uu" and obj["qasm"] is None and obj["noise"] is None
    assert obj["parameters"] == {"theta_c": np.pi / 2, "theta_x": 0.3}
    # depolarizing after each of the two gates shrinks the Bloch vector by (1 - p) twice
    res = runner.invoke(
        app,
        [
            "circuit",
            "uu",
            "--theta-c",
            "pi/2",
            "--theta-x",
            "0.3",
            "--noise",
            "depolarizing:0.3",
            "--json",
        ],
    )
    (obj,) = json_lines(res.stdout)
    assert obj["probabilities"][0] == pytest.approx(0.5 + 0.7**2 * (ideal - 0.5), abs=1e-12)
    assert obj["noise"] == "depolarizing:0.3"


def test_circuit_vqc_matches_qiskit_ordering_and_exports_qasm(tmp_path: Path) -> None:
    args = ["circuit", "vqc", "--x", "0.3,1.2", "--weights", "0.1,0.2,0.3,0.4"]
    res = runner.invoke(app, [*args, "--json"])
    assert res.exit_code == 0, res.output
    (obj,) = json_lines(res.stdout)
    assert obj["states"] == ["00", "01", "10", "11"]
    expected = probabilities(vqc_circuit([[0.3, 1.2]], [0.1, 0.2, 0.3, 0.4]))[0]
    np.testing.assert_allclose(obj["probabilities"], expected, atol=1e-12)
    # the human-readable form: diagram and table
    res = runner.invoke(app, args)
    assert res.exit_code == 0
    assert "Ry(0.4)" in res.stdout or "ry(0.4)" in res.stdout
    assert f"{expected[3]:.6f}" in res.stdout
    pytest.importorskip("qiskit_qasm3_import")
    from qiskit import qasm3
    from qiskit.quantum_info import Statevector

    qasm = tmp_path / "vqc.qasm"
    res = runner.invoke(app, [*args, "--qasm", str(qasm), "--json"])
    assert res.exit_code == 0, res.output
    assert json_lines(res.stdout)[0]["qasm"] == str(qasm)
    loaded = qasm3.loads(qasm.read_text()).remove_final_measurements(inplace=False)
    np.testing.assert_allclose(Statevector(loaded).probabilities(), expected, atol=1e-12)


def test_circuit_aer_and_shots() -> None:
    pytest.importorskip("qiskit_aer")
    args = ["circuit", "vqc", "--x", "0.3,1.2", "--weights", "0.1,0.2,0.3,0.4"]
    noisy = [*args, "--noise", "amplitude-damping:0.2", "--json"]
    numpy_probs = json_lines(runner.invoke(app, noisy).stdout)[0]["probabilities"]
    aer = json_lines(runner.invoke(app, [*noisy, "--backend", "aer"]).stdout)[0]
    np.testing.assert_allclose(aer["probabilities"], numpy_probs, atol=1e-9)
    shots = [*noisy, "--shots", "1000", "--seed", "4"]
    a = json_lines(runner.invoke(app, shots).stdout)[0]["probabilities"]
    assert a == json_lines(runner.invoke(app, shots).stdout)[0]["probabilities"]
    counts = np.array(a) * 1000
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)
    exact = np.array(numpy_probs)
    assert np.all(np.abs(np.array(a) - exact) < 5 * np.sqrt(exact * (1 - exact) / 1000) + 1e-9)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["uu", "--theta-c", "1", "--theta-x", "2", "--noise", "bit-flip:1.5"], "p=1.5 is invalid"),
        (["uu", "--theta-c", "1", "--theta-x", "2", "--noise", "bitflip:0.1"], "channel='bitflip'"),
        (["uu", "--theta-c", "1"], "both --theta-c and --theta-x"),
        (["uu", "--theta-c", "1", "--theta-x", "2", "--x", "1,2"], "only with 'circuit vqc'"),
        (["vqc", "--x", "1,2"], "both --x X1,X2 and --weights"),
        (["vqc", "--x", "1", "--weights", "1,2,3,4"], "x='1' is invalid: 2 comma-separated"),
        (["vqc", "--x", "1,2", "--weights", "1,2,3"], "weights='1,2,3' is invalid"),
        (["ghz"], "circuit='ghz' is invalid: 'uu', 'vqc' or 'head'"),
        (["uu", "--theta-c", "1", "--theta-x", "y"], "theta-x='y' is invalid"),
        (["uu", "--theta-c", "1", "--theta-x", "2", "--backend", "gpu"], "backend='gpu'"),
        (["uu", "--theta-c", "1", "--theta-x", "2", "--shots", "0"], "shots=0 is invalid"),
    ],
)
def test_circuit_bad_input(args: list[str], message: str) -> None:
    res = runner.invoke(app, ["circuit", *args, "--json"])
    assert res.exit_code == 2
    assert res.stdout == ""
    assert message in " ".join(res.stderr.split())


# ---------------------------------------------------------------- noise-sweep


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--p", "0:1"], "p='0:1' is invalid: START:STOP:STEP"),
        (["--p", "0:1.5:0.5"], "p=1.5 is invalid: a probability in [0, 1]"),
        (["--p", "0,x"], "p='0,x' is invalid"),
        (["--channels", "all,bitflip"], "channel='bitflip' is invalid"),
        (["--phase-damping", "both"], "phase_damping='both' is invalid"),
        (["--method", "uu,dnn"], "methods='dnn' is invalid"),
        (["--grouping", "halves"], "grouping='halves' is invalid"),
        (["--readout", "2"], "readout=2.0 is invalid"),
        (["--shots", "-3"], "shots=-3 is invalid"),
        (["--inner-folds", "1"], "inner_folds=1 is invalid"),
        (["--lanes", "x"], "lanes='x' is invalid"),
    ],
)
def test_noise_sweep_bad_options(args: list[str], message: str) -> None:
    res = runner.invoke(app, ["noise-sweep", "--data", "synthetic:track1:30", *args, "--json"])
    assert res.exit_code == 2
    assert res.stdout == ""
    assert message in " ".join(res.stderr.split())


def test_noise_sweep_needs_data_for_direction_methods() -> None:
    res = runner.invoke(app, ["noise-sweep", "--method", "vqc"])
    assert res.exit_code == 2
    assert "data=None is invalid: a dataset (--data) for the uu and vqc methods" in res.stderr


def test_noise_sweep_direction_json_and_figure(tmp_path: Path) -> None:
    plot = tmp_path / "fig.png"
    # seed 3: a drive of 17 left and 43 straight frames
    args = ["noise-sweep", "--data", "synthetic:track1:60", "--seed", "3", "--method", "uu,vqc"]
    args += ["--channels", "bit-flip,phase-damping", "--phase-damping", "paper", "--p", "0:1:0.5"]
    args += ["--folds", "2", "--gap", "0", "--inner-folds", "0", "--plot", str(plot), "--json"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    rows = json_lines(res.stdout)
    assert len(rows) == 2 * 2 * 3
    assert {(r["method"], r["channel"], r["p"]) for r in rows} == {
        (m, c, p)
        for m in ("uu", "vqc")
        for c in ("bit-flip", "phase-damping-paper")
        for p in (0.0, 0.5, 1.0)
    }
    for r in rows:
        assert r["dataset"] == "synthetic-track1" and r["n_test"] == 60
        assert r["trained_under_noise"] is False and r["phase_damping_form"] == "paper"
        assert 0.0 <= r["accuracy"] <= 1.0 and r["seed"] == 3 and r["shots"] is None
    assert plot.read_bytes()[:4] == b"\x89PNG"
    assert not (tmp_path / "fig_shadow.png").exists()
    # same seed: the same JSON (features now come from the cache)
    again = runner.invoke(app, args)
    assert again.stdout == res.stdout


def test_noise_sweep_shadow_set_with_a_bad_file(tmp_path: Path) -> None:
    images, masks = synthetic_shadow_set(4, seed=2)
    root = tmp_path / "set"
    for i, (im, m) in enumerate(zip(images, masks, strict=True)):
        write_image(root / "images" / f"s{i}.png", im)
        write_mask(root / "masks" / f"s{i}.png", m)
    (root / "images" / "zz_broken.png").write_bytes(b"not a png")
    plot = tmp_path / "ber.png"
    args = ["noise-sweep", "--shadow-set", str(root), "--method", "uu-shadow"]
    args += ["--channels", "depolarizing", "--p", "0,1", "--plot", str(plot), "--json"]
    res = runner.invoke(app, args)
    assert res.exit_code == 1, res.output
    *rows, summary = json_lines(res.stdout)
    assert [r["p"] for r in rows] == [0.0, 1.0]
    assert all(r["method"] == "uu-shadow" and r["dataset"] == "set" for r in rows)
    assert rows[0]["ber"] < 30 and rows[1]["ber"] == 50.0
    assert summary["summary"] is True and "zz_broken.png" in summary["failures"][0]["error"]
    assert plot.read_bytes()[:4] == b"\x89PNG"  # shadow only: the figure goes to --plot


def test_noise_sweep_table_output() -> None:
    args = ["noise-sweep", "--data", "synthetic:track1:60", "--seed", "3", "--method", "uu"]
    args += ["--channels", "depolarizing", "--p", "0,0.5", "--folds", "2", "--inner-folds", "0"]
    args += ["--train-under-noise", "--shots", "128", "--readout", "0.01"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    text = res.stdout
    assert "image-split-uu accuracy, synthetic-track1 (60 test frames)" in text
    assert "trained under noise; 128 shots; readout error 0.01" in text
    assert "0.5" in text and "depolar." in text


def test_circuit_head_prints_expectations_and_probabilities() -> None:
    from qdcnn.quantum.templates import head_readout

    w = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2]
    args = ["circuit", "head", "--qubits", "2", "--layers", "2", "--x", "0.3,-0.5"]
    res = runner.invoke(app, [*args, "--weights", ",".join(map(str, w)), "--json"])
    assert res.exit_code == 0, res.output
    (obj,) = json_lines(res.stdout)
    expected = head_readout([[0.3, -0.5]], np.reshape(w, (2, 2, 3)))
    np.testing.assert_allclose(obj["probabilities"], expected["probabilities"][0], atol=1e-12)
    np.testing.assert_allclose(obj["expectations"], expected["expectations"][0], atol=1e-12)
    res = runner.invoke(app, [*args, "--weights", "0.1,0.2"])
    assert (
        res.exit_code == 2
        and "weights='0.1,0.2' is invalid: 12 comma-separated angles" in res.stderr
    )
    res = runner.invoke(
        app, ["circuit", "head", "--qubits", "9", "--layers", "1", "--weights", "0"]
    )
    assert res.exit_code == 2 and "qubits=9 is invalid" in res.stderr


def test_the_trained_head_of_a_saved_model_exports_and_runs_on_aer(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    pytest.importorskip("qiskit_qasm3_import")
    pytest.importorskip("qiskit_aer")
    from qiskit import qasm3, transpile
    from qiskit_aer import AerSimulator

    from qdcnn.config import PipelineConfig
    from qdcnn.direction.methods import TrainingOptions
    from qdcnn.direction.model import train_direction_model

    rng = np.random.default_rng(0)
    images = rng.integers(0, 255, (12, 40, 80, 3), dtype=np.uint8)
    options = TrainingOptions(epochs=1, threads=1, params={"val_fraction": 0.0})
    model = train_direction_model(
        "qdcnn-head", images, np.repeat([0, 1, 2], 4), PipelineConfig(), "toy", inner_folds=0,
        options=options,
    )  # fmt: skip
    path = model.save(tmp_path / "hybrid.safetensors")
    qasm = tmp_path / "head.qasm"
    res = runner.invoke(
        app,
        [
            "circuit",
            "head",
            "--model",
            str(path),
            "--x",
            "0.1,0.2,0.3,0.4",
            "--qasm",
            str(qasm),
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    (obj,) = json_lines(res.stdout)
    weights = model.estimator.model_.head.weights.detach().numpy().ravel()
    np.testing.assert_allclose(obj["parameters"]["weights"], weights, atol=1e-7)
    circuit = qasm3.loads(qasm.read_text())
    counts = AerSimulator(method="statevector").run(
        transpile(circuit), shots=20000, seed_simulator=1
    )
    hist = counts.result().get_counts()
    aer = np.array([hist.get(format(i, "04b"), 0) for i in range(16)]) / 20000
    assert np.abs(aer - np.array(obj["probabilities"])).max() < 0.02  # 20,000 shots


def test_noise_sweep_takes_evaluates_lane_options_and_says_what_auto_estimated() -> None:
    args = ["noise-sweep", "--data", "synthetic:track1:60", "--seed", "3", "--method", "uu"]
    args += ["--channels", "bit-flip", "--p", "0", "--folds", "2", "--inner-folds", "0"]
    args += ["--lanes", "auto", "--edges", "rgb", "--track", "ema", "--json"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    notes = [line for line in res.stderr.splitlines() if line.startswith("note:")]
    assert notes[0].startswith("note: synthetic-track1: camera 320x160: horizon at")
    (row,) = json_lines(res.stdout)
    assert row["method"] == "uu" and 0.0 <= row["accuracy"] <= 1.0
