"""Hybrid-network timings: the quantum head against PennyLane, and its cost in a CNN epoch.

Three cases, all measured in one run (the ratios compare numbers from the same run):

* ``head_statevector``: forward + backward of the 4-qubit, 2-layer head circuit
  (``AngleEmbedding(rotation="Y")`` + ``StronglyEntanglingLayers``, ``<Z_i>`` read-out)
  on a batch of 256 angle vectors, qdcnn's torch simulator against PennyLane's
  ``qml.qnn.TorchLayer`` on ``default.qubit`` (``diff_method="backprop"``, parameter
  broadcasting). Outputs and gradients (inputs and weights) are asserted equal to 1e-6.
* ``head_density_depolarizing``: the same with depolarizing noise (p = 0.05) after every
  gate on every qubit it touches: qdcnn's density-matrix simulator against PennyLane's
  ``default.mixed`` with ``qml.QubitChannel`` of the same Kraus operators; asserted equal.
* ``epoch_qdcnn_head_vs_twin``: one training epoch (600 frames of a 320x160 synthetic
  ``track1`` drive, PilotNet preprocessing done once beforehand, batch 16, AdamW,
  cross-entropy) of ``qdcnn-head`` and of its classical twin, in a minimal loop.

Times are measured wall-clock seconds (``time.perf_counter``), the median of
``--repeats`` runs after a warm-up; float64 for the head cases (the 1e-6 checks),
float32 for the epochs. torch runs on one thread; run it on one core::

    taskset -c 0 python benchmarks/bench_hybrid.py [--json] [--repeats 7] [--frames 600]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from qdcnn.quantum.noise import NoiseSpec, depolarizing
from qdcnn.quantum.templates import head_template
from qdcnn.quantum.torchsim import TorchCircuit

N_QUBITS, N_LAYERS, BATCH, P_NOISE = 4, 2, 256, 0.05


def median_time(fn: Callable[[], object], repeats: int, warmup: int = 2) -> float:
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def pennylane_layer(noise: bool) -> Any:
    import pennylane as qml

    n = N_QUBITS
    kraus = list(depolarizing(P_NOISE))
    device = qml.device("default.mixed" if noise else "default.qubit", wires=n)

    @qml.qnode(device, interface="torch", diff_method="backprop")
    def circuit(inputs: Any, weights: Any) -> Any:
        if not noise:
            qml.AngleEmbedding(inputs, wires=range(n), rotation="Y")
            qml.StronglyEntanglingLayers(weights, wires=range(n))
        else:  # the same gates, each followed by the channel on its qubits
            ranges = [(layer % (n - 1)) + 1 for layer in range(N_LAYERS)]
            with qml.QueuingManager.stop_recording():
                gates = [qml.RY(inputs[..., i], wires=i) for i in range(n)]
                gates += qml.StronglyEntanglingLayers.compute_decomposition(
                    weights, wires=range(n), ranges=ranges
                )
            for op in gates:
                qml.apply(op)
                for wire in op.wires:
                    qml.QubitChannel(kraus, wires=wire)
        return [qml.expval(qml.PauliZ(i)) for i in range(n)]

    return qml.qnn.TorchLayer(circuit, {"weights": (N_LAYERS, N_QUBITS, 3)}).double()


def head_case(noise: bool, repeats: int) -> dict[str, Any]:
    rng = np.random.default_rng(0)
    x0 = torch.as_tensor(rng.uniform(-np.pi, np.pi, (BATCH, N_QUBITS)))
    w0 = torch.as_tensor(rng.uniform(0, 2 * np.pi, (N_LAYERS, N_QUBITS, 3)))
    coef = torch.as_tensor(rng.normal(size=(BATCH, N_QUBITS)))
    spec = NoiseSpec("depolarizing", P_NOISE) if noise else None
    ours = TorchCircuit(head_template(N_QUBITS, N_LAYERS), spec)
    layer = pennylane_layer(noise)
    with torch.no_grad():
        layer.weights.copy_(w0)

    def run_ours() -> tuple[torch.Tensor, ...]:
        x = x0.clone().requires_grad_(True)
        w = w0.clone().requires_grad_(True)
        out = ours.expectations(x, w.reshape(-1))
        (out * coef).sum().backward()
        assert x.grad is not None and w.grad is not None
        return out.detach(), x.grad, w.grad

    def run_pennylane() -> tuple[torch.Tensor, ...]:
        x = x0.clone().requires_grad_(True)
        layer.zero_grad()
        out = layer(x)
        (out * coef).sum().backward()
        assert x.grad is not None and layer.weights.grad is not None
        return out.detach(), x.grad, layer.weights.grad.clone()

    diffs = [float((a - b).abs().max()) for a, b in zip(run_ours(), run_pennylane(), strict=True)]
    assert max(diffs) < 1e-6, (
        f"qdcnn and PennyLane differ by {diffs} (outputs, input and weight gradients)"
    )
    t_ours = median_time(run_ours, repeats)
    t_pl = median_time(run_pennylane, max(3, repeats // 2) if noise else repeats)
    name = "head_density_depolarizing" if noise else "head_statevector"
    return {
        "name": name,
        "batch": BATCH,
        "qubits": N_QUBITS,
        "layers": N_LAYERS,
        "qdcnn_s": t_ours,
        "pennylane_s": t_pl,
        "ratio_vs_pennylane": t_pl / t_ours,
        "max_abs_difference": max(diffs),
    }


def epoch_case(frames: int, repeats: int) -> dict[str, Any]:
    from qdcnn.data.synthetic import generate_drive
    from qdcnn.models.hybrid import build_hybrid, trainable_parameters
    from qdcnn.models.preprocess import PILOTNET_INPUT, crop_resize, normalise

    scenes = generate_drive("track1", frames, seed=0)
    images = crop_resize(np.stack([s.image for s in scenes]), PILOTNET_INPUT)
    labels = torch.as_tensor([s.direction for s in scenes])
    order = torch.randperm(frames, generator=torch.Generator().manual_seed(0))
    batches = [order[i : i + 16] for i in range(0, frames, 16)]

    def make(head: str) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
        torch.manual_seed(0)
        net = build_hybrid("qdcnn-head", head=head)
        return net, torch.optim.AdamW(net.parameters(), lr=1e-3)

    nets = {head: make(head) for head in ("quantum", "classical")}

    def epoch(head: str) -> None:
        net, opt = nets[head]
        net.train()
        for idx in batches:
            x = normalise(images[idx], PILOTNET_INPUT)
            opt.zero_grad()
            torch.nn.functional.cross_entropy(net(x), labels[idx]).backward()
            opt.step()

    times: dict[str, list[float]] = {"quantum": [], "classical": []}
    for head in times:  # warm-up
        epoch(head)
    for _ in range(repeats):
        for head in times:  # alternate, so that a slow spell of the machine hits both
            t0 = time.perf_counter()
            epoch(head)
            times[head].append(time.perf_counter() - t0)
    quantum, classical = (statistics.median(times[h]) for h in ("quantum", "classical"))
    return {
        "name": "epoch_qdcnn_head_vs_twin",
        "frames": frames,
        "batch": 16,
        "parameters": trainable_parameters(nets["quantum"][0]),
        "quantum_epoch_s": quantum,
        "twin_epoch_s": classical,
        "ratio_vs_twin": quantum / classical,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="one JSON object per case")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--epoch-repeats", type=int, default=3)
    parser.add_argument("--frames", type=int, default=600)
    args = parser.parse_args()
    torch.set_num_threads(1)
    cases = [
        head_case(False, args.repeats),
        head_case(True, args.repeats),
        epoch_case(args.frames, args.epoch_repeats),
    ]
    for case in cases:
        if args.json:
            print(json.dumps(case))
        else:
            times = {k: round(v, 6) for k, v in case.items() if k.endswith("_s")}
            ratio = next(v for k, v in case.items() if k.startswith("ratio"))
            print(f"{case['name']}: {times} ratio {ratio:.2f} (measured)")


if __name__ == "__main__":
    main()
