"""``qdcnn noise-sweep`` and ``qdcnn circuit``: noise robustness (Fig. 7) and circuit inspection.

The lead's :mod:`qdcnn.cli` registers both::

    app.command("noise-sweep")(noise_sweep_cmd)
    app.command("circuit")(circuit_cmd)

Output follows :mod:`qdcnn.cli_common`: with ``--json`` stdout carries only JSON objects,
one per line; progress and errors go to stderr; exit 0 when everything worked, 1 when some
input files failed (the rest is still used and reported), 2 for bad options.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.table import Table

from qdcnn.cli._common import CliReporter, JsonOpt, emit, out, report_error
from qdcnn.cli._common import fail as fail_on_error
from qdcnn.errors import ParameterError, QdcnnError

# ---------------------------------------------------------------- noise-sweep


def _sweep_config(lanes: str, seed: int) -> Any:
    from qdcnn.config import LaneConfig
    from qdcnn.experiments.direction_model import default_config

    if lanes not in ("udacity", "paper"):
        raise ParameterError("lanes", lanes, "'udacity' (1 smoothing pass) or 'paper' (30 passes)")
    cfg = replace(default_config(), seed=seed)
    return cfg if lanes == "udacity" else replace(cfg, lanes=LaneConfig())


def _parse_groupings(text: str) -> tuple[str, ...]:
    from qdcnn.pipeline import GROUPINGS

    names = tuple(dict.fromkeys(t.strip() for t in text.split(",") if t.strip()))
    bad = [g for g in names if g not in GROUPINGS]
    if bad or not names:
        raise ParameterError("grouping", text, "a comma list of " + ", ".join(GROUPINGS))
    return names


_SHORT_CHANNEL = {
    "bit-flip": "bit flip",
    "phase-flip": "phase flip",
    "bit-phase-flip": "bit-phase",
    "depolarizing": "depolar.",
    "amplitude-damping": "amp. damp.",
    "phase-damping": "phase damp.",
    "phase-damping-paper": "ph. damp. (paper)",
}


def _print_tables(result: Any) -> None:
    """One table per method: a row per strength, a column per channel."""
    from qdcnn.experiments.noise_sweep import SHADOW_METHOD

    for label in result.labels():
        shadow = label == SHADOW_METHOD
        rows = [r for r in result.rows if r.label == label]
        what = "BER (%)" if shadow else "accuracy"
        data = result.shadow_set if shadow else result.dataset
        unit = "images" if shadow else "frames"
        title = f"{label} {what}, {data} ({rows[0].n_test} test {unit})"
        heads = [_SHORT_CHANNEL.get(ch, ch) for ch in result.channels]
        table = Table("p", *heads)
        values = {(r.channel, r.p): (r.ber if shadow else r.accuracy) for r in rows}
        fmt = "{:.1f}" if shadow else "{:.3f}"
        for p in result.strengths:
            cells = [values.get((ch, p)) for ch in result.channels]
            table.add_row(f"{p:g}", *("-" if v is None else fmt.format(v) for v in cells))
        out.print(title)
        out.print(table)
    trained = "trained under noise" if result.trained_under_noise else "trained without noise"
    readout = f"; readout error {result.readout:g}" if result.readout else ""
    out.print(f"{trained}; {result.evaluation}{readout}")
    form = result.phase_damping_form
    if form:
        out.print(f"phase damping: {form}")
    baseline = next((r.majority_baseline for r in result.rows if r.majority_baseline), None)
    if baseline is not None:
        out.print(f"majority-class baseline: {baseline:.3f}")
    proto = result.protocol
    if "folds" in proto:
        out.print(
            f"{proto['folds']} contiguous folds (gap {proto['gap']}, "
            f"inner CV {proto['inner_folds']})"
        )


def noise_sweep_cmd(
    data: Annotated[
        str | None,
        typer.Option(help="Direction data: udacity:PATH | carla:PATH | synthetic:PRESET[:N]."),
    ] = None,
    methods: Annotated[
        str, typer.Option(help="Comma list of uu, vqc, uu-shadow (or all).")
    ] = "uu,vqc",
    channels: Annotated[
        str,
        typer.Option(
            help="'all' (the six of Fig. 7) or a comma list: bit-flip, phase-flip, "
            "bit-phase-flip, depolarizing, amplitude-damping, phase-damping, "
            "phase-damping-paper."
        ),
    ] = "all",
    p: Annotated[
        str,
        typer.Option("--p", help="Strengths: START:STOP:STEP (STOP included) or a comma list."),
    ] = "0:0.99:0.11",
    phase_damping: Annotated[
        str,
        typer.Option(
            help="What 'phase-damping' means: textbook (Qiskit's phase_damping_error) "
            "or paper (the printed operators)."
        ),
    ] = "textbook",
    grouping: Annotated[
        str, typer.Option(help="Lane grouping(s), comma list: image-split, kmeans, spectral.")
    ] = "image-split",
    train_under_noise: Annotated[
        bool,
        typer.Option(
            "--train-under-noise",
            help="Retrain under each noise setting (default: train once without noise).",
        ),
    ] = False,
    shots: Annotated[
        int | None,
        typer.Option(help="Shots per circuit at evaluation (default: exact probabilities)."),
    ] = None,
    readout: Annotated[
        float, typer.Option(help="Readout error added at every point, in [0, 1].")
    ] = 0.0,
    folds: Annotated[int, typer.Option(help="Contiguous cross-validation folds.")] = 5,
    gap: Annotated[
        int, typer.Option(help="Frames left out of training on each side of a test block.")
    ] = 5,
    inner_folds: Annotated[
        int, typer.Option(help="Inner folds choosing hyperparameters (0: none).")
    ] = 3,
    lanes: Annotated[
        str, typer.Option(help="Lane settings: udacity (1 smoothing pass) | paper (30).")
    ] = "udacity",
    shadow_set: Annotated[
        Path | None,
        typer.Option(
            help="Shadow set DIR/images/* + DIR/masks/<stem>.png for uu-shadow "
            "(implies uu-shadow; default: synthetic track2 scenes)."
        ),
    ] = None,
    shadow_frames: Annotated[
        int, typer.Option(help="Synthetic track2 scenes for uu-shadow (half train, half test).")
    ] = 24,
    plot: Annotated[
        Path | None,
        typer.Option(help="Write the accuracy figure here (shadow BER: NAME_shadow.EXT)."),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of every random choice.")] = 0,
    cache: Annotated[bool, typer.Option(help="Reuse cached lane features.")] = True,
    as_json: JsonOpt = False,
) -> None:
    """Accuracy against noise strength for each channel and method (the paper's Fig. 7).

    Models are trained once without noise and evaluated under each (channel, p) with exact
    density-matrix probabilities, unless --train-under-noise or --shots say otherwise.
    Noise acts after every gate on every qubit the gate touches, as in a Qiskit Aer
    NoiseModel. uu-shadow adds the UU-dagger shadow detector's BER on images with masks.
    """
    from qdcnn.experiments import noise_sweep as ns

    try:
        method_list = ns.parse_methods(methods)
        if shadow_set is not None and ns.SHADOW_METHOD not in method_list:
            method_list = (*method_list, ns.SHADOW_METHOD)
        channel_list = ns.parse_channels(channels, phase_damping)
        strengths = ns.parse_strengths(p)
        groupings = _parse_groupings(grouping)
        ns.check_probability("readout", readout)
        if shots is not None:
            from qdcnn.quantum.sampling import check_shots

            check_shots(shots)
        if inner_folds < 0 or inner_folds == 1:
            raise ParameterError("inner_folds", inner_folds, "0 (none) or at least 2")
        cfg = _sweep_config(lanes, seed)
        direction = [m for m in method_list if m in ns.DIRECTION_METHODS]
        if direction and data is None:
            raise ParameterError("data", None, "a dataset (--data) for the uu and vqc methods")
    except QdcnnError as exc:
        raise fail_on_error(exc) from None

    failures: list[Any] = []
    rows: list[Any] = []
    dataset = shadow_name = None
    protocol: dict[str, Any] = {}
    n_points = len(channel_list) * len(strengths)
    try:
        if direction:
            assert data is not None
            from qdcnn.data.frames import load_frameset
            from qdcnn.data.labels import check_labels_usable
            from qdcnn.experiments.features import compute_features
            from qdcnn.experiments.protocol import ContiguousKFold

            frames = load_frameset(data, seed=seed)
            for problem in frames.problems:
                report_error(str(problem))
            ContiguousKFold(folds, gap).check(len(frames))  # checks folds and gap before any work
            with CliReporter(False).progress(len(frames), f"lane features ({frames.name})") as bar:
                table = compute_features(frames, cfg, groupings, use_cache=cache, on_frame=bar)
            failures.extend(table.failures)
            keep = table.readable
            labels = frames.labels(cfg.labels)[keep]
            check_labels_usable(labels, source=data)
            dataset = frames.name
            protocol.update(folds=folds, gap=gap, inner_folds=inner_folds)
            total = len(direction) * len(groupings) * n_points
            with CliReporter(False).progress(total, "noise sweep") as bar:
                rows += ns.direction_sweep(
                    {g: table.features[g][keep] for g in groupings},
                    labels,
                    methods=direction,
                    channels=channel_list,
                    strengths=strengths,
                    config=cfg,
                    folds=folds,
                    gap=gap,
                    inner_folds=inner_folds,
                    train_under_noise=train_under_noise,
                    shots=shots,
                    readout=readout,
                    seed=seed,
                    on_step=bar,
                )
        if ns.SHADOW_METHOD in method_list:
            if shadow_set is not None:
                from qdcnn.data.shadow_set import load_shadow_set

                images, masks, shadow_failures = load_shadow_set(shadow_set)
                failures.extend(shadow_failures)
                shadow_name = shadow_set.resolve().name
            else:
                images, masks = ns.synthetic_shadow_set(shadow_frames, seed=seed)
                shadow_name = "synthetic-track2-scenes"
            tr, te = ns.split_train_test(len(images))
            protocol.update(shadow_train=tr.stop - tr.start, shadow_test=te.stop - te.start)
            with CliReporter(False).progress(n_points, "shadow noise sweep") as bar:
                shadow_rows, _ = ns.shadow_sweep(
                    images[tr],
                    masks[tr],
                    images[te],
                    masks[te],
                    channels=channel_list,
                    strengths=strengths,
                    config=cfg.shadow,
                    train_under_noise=train_under_noise,
                    shots=shots,
                    readout=readout,
                    seed=seed,
                    on_step=bar,
                )
            rows += shadow_rows
        result = ns.NoiseSweepResult(
            dataset,
            rows,
            channel_list,
            strengths,
            train_under_noise,
            shots,
            readout,
            seed,
            shadow_name,
            protocol,
        )
        written = _write_plots(result, plot, direction, ns.SHADOW_METHOD in method_list)
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    for f in failures:
        report_error(f.error)
    if as_json:
        for obj in result.to_dicts():
            emit(obj)
        if failures:
            emit({"summary": True, "failures": [f.to_dict() for f in failures]})
    else:
        _print_tables(result)
        for path in written:
            out.print(f"figure written to {path}")
    raise typer.Exit(1 if failures else 0)


def _write_plots(result: Any, plot: Path | None, direction: list[str], shadow: bool) -> list[Path]:
    if plot is None:
        return []
    from qdcnn.experiments.noise_plot import (
        accuracy_figure,
        save_figure,
        shadow_figure,
        shadow_plot_path,
    )

    written = []
    if direction:
        written.append(save_figure(accuracy_figure(result), plot))
    if shadow:
        target = shadow_plot_path(plot) if direction else plot
        written.append(save_figure(shadow_figure(result), target))
    return written


# ---------------------------------------------------------------- circuit

_PI_TERM = re.compile(
    r"^\s*(?P<sign>[+-]?)\s*(?:(?P<num>\d+(?:\.\d*)?|\.\d+)\s*\*?\s*)?pi"
    r"\s*(?:/\s*(?P<den>\d+(?:\.\d*)?|\.\d+))?\s*$"
)


def parse_angle(text: str, name: str) -> float:
    """An angle in radians: a number, or a multiple of pi (``pi/2``, ``-3pi/4``, ``2*pi``).

    Examples
    --------
    >>> parse_angle("-3pi/4", "theta") == -3 * math.pi / 4
    True
    """
    try:
        value = float(text)
    except ValueError:
        m = _PI_TERM.match(text)
        if m is None:
            raise ParameterError(name, text, "an angle in radians, e.g. 1.2 or pi/2") from None
        value = (-1.0 if m["sign"] == "-" else 1.0) * float(m["num"] or 1.0) * math.pi
        if m["den"] is not None:
            den = float(m["den"])
            if den == 0:
                raise ParameterError(name, text, "a non-zero denominator") from None
            value /= den
    if not math.isfinite(value):
        raise ParameterError(name, text, "a finite angle")
    return value


def _angle_list(text: str, name: str, count: int | None = None) -> list[float]:
    values = [parse_angle(t, name) for t in text.split(",") if t.strip()]
    if count is not None and len(values) != count:
        raise ParameterError(name, text, f"{count} comma-separated angles")
    return values


def _build_circuit(
    kind: str,
    theta_c: str | None,
    theta_x: str | None,
    x: str | None,
    weights: str | None,
    feature_map_reps: int,
) -> tuple[Any, dict[str, Any]]:
    from qdcnn.quantum.circuits import uu_dagger_circuit, vqc_circuit

    if kind == "uu":
        if x is not None or weights is not None:
            raise ParameterError("x/weights", x or weights, "only with 'circuit vqc'")
        if theta_c is None or theta_x is None:
            raise ParameterError("theta-c/theta-x", None, "both --theta-c and --theta-x for uu")
        tc, tx = parse_angle(theta_c, "theta-c"), parse_angle(theta_x, "theta-x")
        return uu_dagger_circuit(tc, tx), {"theta_c": tc, "theta_x": tx}
    if kind == "vqc":
        if theta_c is not None or theta_x is not None:
            raise ParameterError("theta-c/theta-x", theta_c or theta_x, "only with 'circuit uu'")
        if x is None or weights is None:
            raise ParameterError("x/weights", None, "both --x X1,X2 and --weights W1,... for vqc")
        if isinstance(feature_map_reps, bool) or feature_map_reps < 1:
            raise ParameterError("feature-map-reps", feature_map_reps, "an integer >= 1")
        xs = _angle_list(x, "x", 2)
        ws = _angle_list(weights, "weights")
        if len(ws) < 2 or len(ws) % 2:
            raise ParameterError("weights", weights, "2 (reps + 1) angles: 4 for the paper's VQC")
        circuit = vqc_circuit(
            [xs], ws, feature_map_reps=feature_map_reps, ansatz_reps=len(ws) // 2 - 1
        )
        params = {"x": xs, "weights": ws, "feature_map_reps": feature_map_reps}
        return circuit, params
    raise ParameterError("circuit", kind, "'uu' or 'vqc'")


def circuit_cmd(
    kind: Annotated[str, typer.Argument(help="uu (UU-dagger fidelity test) | vqc (2-qubit VQC)")],
    theta_c: Annotated[
        str | None,
        typer.Option("--theta-c", help="uu: centroid angle in radians (e.g. 1.2 or pi/2)."),
    ] = None,
    theta_x: Annotated[
        str | None, typer.Option("--theta-x", help="uu: test-value angle in radians.")
    ] = None,
    x: Annotated[
        str | None, typer.Option("--x", help="vqc: the two feature-map angles X1,X2.")
    ] = None,
    weights: Annotated[
        str | None,
        typer.Option(help="vqc: ansatz angles W1,W2,W3,W4 (2 (reps + 1) of them)."),
    ] = None,
    feature_map_reps: Annotated[
        int, typer.Option(help="vqc: repetitions of the ZZ feature map.")
    ] = 2,
    noise: Annotated[
        str | None,
        typer.Option(help="CHANNEL:P[,readout:E], e.g. depolarizing:0.1 (density matrix)."),
    ] = None,
    shots: Annotated[
        int | None, typer.Option(help="Shot estimates (default: exact probabilities).")
    ] = None,
    backend: Annotated[str, typer.Option(help="numpy | aer")] = "numpy",
    seed: Annotated[int, typer.Option(help="Seed of the shots.")] = 0,
    qasm: Annotated[
        Path | None, typer.Option(help="Write the circuit as OpenQASM 3 (measured) to this file.")
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Print a circuit's diagram and outcome probabilities; optionally export OpenQASM 3.

    Probabilities are indexed by basis state with qubit 0 the least significant bit, as in
    Qiskit. With --noise the channel acts after every gate on every qubit it touches.
    """
    from qdcnn._optional import has_module
    from qdcnn.quantum.execute import check_backend, run_probabilities
    from qdcnn.quantum.export import draw_text, write_qasm3
    from qdcnn.quantum.noise import parse_noise
    from qdcnn.quantum.sampling import check_shots

    try:
        circuit, params = _build_circuit(kind, theta_c, theta_x, x, weights, feature_map_reps)
        spec = None if noise is None else parse_noise(noise)
        check_backend(backend)
        if shots is not None:
            check_shots(shots)
        probs = run_probabilities(
            circuit, shots=shots, noise=spec, backend=backend, rng=np.random.default_rng(seed)
        )[0]
        diagram = draw_text(circuit)
        qasm_path = None
        if qasm is not None:
            checked = has_module("qiskit_qasm3_import")
            qasm_path = write_qasm3(circuit, qasm, check=checked)
            if not checked:
                report_error(
                    "OpenQASM 3 written without the read-back check: "
                    "pip install qiskit-qasm3-import"
                )
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    n = circuit.num_qubits
    states = [format(i, f"0{n}b") for i in range(2**n)]
    if as_json:
        emit(
            {
                "circuit": kind,
                "parameters": params,
                "num_qubits": n,
                "noise": None if spec is None else spec.label(),
                "shots": shots,
                "backend": backend,
                "seed": seed,
                "states": states,
                "probabilities": [float(v) for v in probs],
                "qasm": None if qasm_path is None else str(qasm_path),
                "diagram": diagram,
            }
        )
        raise typer.Exit(0)
    out.print(diagram, markup=False, highlight=False, soft_wrap=True)
    how = "exact" if shots is None else f"{shots} shots, seed {seed}"
    noise_label = "no noise" if spec is None else f"noise {spec.label()}"
    out.print(f"outcome probabilities: {backend} backend, {how}, {noise_label}")
    table = Table(f"state (q{n - 1}..q0)" if n > 1 else "state (q0)", "index", "probability")
    for i, (s, v) in enumerate(zip(states, probs, strict=True)):
        table.add_row(s, str(i), f"{v:.6f}")
    out.print(table)
    if qasm_path is not None:
        out.print(f"OpenQASM 3 written to {qasm_path}")
    raise typer.Exit(0)
