"""Training time of qdcnn's VQC against qiskit-machine-learning's VQC, and of the UU rule.

Both VQCs train the same circuit (``zz_feature_map(2)`` + ``real_amplitudes(2, reps=1)``),
from the same initial point, with COBYLA(maxiter) on the same scaled features, one-hot
targets, MSE ("squared_error") loss, ``output_shape=3`` and the same interpret map.
qiskit-machine-learning uses its default exact sampler (``QMLSampler()``, Statevector).
Imports and one warm-up fit are outside the timed region; the reported time is the best
of ``--repeats`` fits (qiskit-ml: ``--qiskit-repeats``).

Usage::

    python benchmarks/bench_vqc.py [--n 300] [--maxiter 30] [--repeats 5] [--qiskit-repeats 1]
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from collections.abc import Callable

import numpy as np

from qdcnn.quantum.direction import UUDirectionClassifier
from qdcnn.quantum.vqc import Interpret, VQCClassifier


def road_slopes(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Synthetic ``[slope_left, slope_right]``: straight symmetric, bends shift both slopes."""
    rng = np.random.default_rng(seed)
    y = rng.integers(0, 3, n)
    spread = rng.uniform(0.8, 1.2, n)
    shift = np.select([y == 0, y == 2], [1.0, -1.0], 0.0) * rng.uniform(0.6, 0.9, n)
    X = np.stack([-spread + shift, spread + shift], axis=1) + rng.normal(0, 0.05, (n, 2))
    return X, y


def best_time(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=300)
    parser.add_argument("--maxiter", type=int, default=30)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--qiskit-repeats", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from qiskit.circuit.library import real_amplitudes, zz_feature_map
    from qiskit_machine_learning.algorithms import VQC
    from qiskit_machine_learning.optimizers import COBYLA
    from qiskit_machine_learning.primitives import QMLSampler

    X, y = road_slopes(args.n, args.seed)
    ours = VQCClassifier(maxiter=args.maxiter, seed=args.seed)
    ours.fit(X, y)  # warm-up; also gives the scaling and initial point both engines share
    t_ours = best_time(lambda: ours.fit(X, y), args.repeats)

    angles = ours.scale_features(X)
    onehot = np.eye(3)[y]
    history: list[float] = []

    def qiskit_fit() -> VQC:
        history.clear()
        vqc = VQC(
            feature_map=zz_feature_map(2),
            ansatz=real_amplitudes(2, reps=1),
            loss="squared_error",
            optimizer=COBYLA(maxiter=args.maxiter),
            initial_point=ours.initial_weights_.copy(),
            callback=lambda _w, value: history.append(float(value)),
            sampler=QMLSampler(),
            interpret=Interpret(ours.interpret),
            output_shape=3,
        )
        return vqc.fit(angles, onehot)

    qiskit_fit()  # warm-up (transpilation caches, lazy imports)
    t_qiskit = best_time(qiskit_fit, args.qiskit_repeats)
    theirs = qiskit_fit()
    qiskit_pred = np.argmax(theirs.predict(angles), axis=1)

    uu = UUDirectionClassifier()
    uu.fit(X, y)
    t_uu_fit = best_time(lambda: uu.fit(X, y), args.repeats)
    t_uu_pred = best_time(lambda: uu.predict(X), args.repeats)
    uu_exact = UUDirectionClassifier(shots=None).fit(X, y)
    t_uu_pred_exact = best_time(lambda: uu_exact.predict(X), args.repeats)

    report = {
        "n_samples": args.n,
        "maxiter": args.maxiter,
        "machine": f"{platform.processor() or platform.machine()}, {platform.python_version()}",
        "vqc_train_s": {"qdcnn": t_ours, "qiskit_machine_learning": t_qiskit},
        "vqc_speedup": t_qiskit / t_ours,
        "vqc_objective_evaluations": {
            "qdcnn": len(ours.objective_history_),
            "qiskit_ml": len(history),
        },
        "vqc_final_objective": {
            "qdcnn": ours.objective_,
            "qiskit_ml": float(theirs.fit_result.fun),
        },
        "vqc_max_abs_history_difference": float(
            np.max(np.abs(np.asarray(ours.objective_history_) - np.asarray(history)))
        ),
        "vqc_train_accuracy": {
            "qdcnn": float(ours.score(X, y)),
            "qiskit_ml": float(np.mean(qiskit_pred == y)),
        },
        "uu_fit_s": t_uu_fit,
        "uu_predict_s_1024_shots": t_uu_pred,
        "uu_predict_s_exact": t_uu_pred_exact,
        "uu_train_accuracy": uu.train_accuracy_,
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
