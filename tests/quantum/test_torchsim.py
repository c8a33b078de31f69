"""The PyTorch simulator against the NumPy simulator, Qiskit Aer, the parameter-shift rule."""

from __future__ import annotations

import numpy as np
import pytest
from all_gates import random_all_gates_circuit

torch = pytest.importorskip("torch")

from qdcnn.errors import ParameterError  # noqa: E402
from qdcnn.quantum import gates as np_gates  # noqa: E402
from qdcnn.quantum.circuits import (  # noqa: E402
    GATE_NAMES,
    TWO_QUBIT,
    CircuitBuilder,
    Gate,
    TemplateBuilder,
)
from qdcnn.quantum.noise import CHANNELS, NoiseSpec, depolarizing  # noqa: E402
from qdcnn.quantum.simulator import density_matrix, embed, probabilities, statevector  # noqa: E402
from qdcnn.quantum.templates import head_template  # noqa: E402
from qdcnn.quantum.torchsim import MAX_QUBITS, TorchCircuit, gate_channels  # noqa: E402
from qdcnn.quantum.torchsim.gates import gate_matrices  # noqa: E402


@pytest.fixture(autouse=True)
def _one_torch_thread():  # type: ignore[no-untyped-def]
    """Small tensors: a second intra-op thread only adds contention on a shared machine."""
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


def _tensors(inputs, weights, dtype=torch.float64, device="cpu"):  # type: ignore[no-untyped-def]
    return (
        torch.as_tensor(inputs, dtype=dtype, device=device),
        torch.as_tensor(weights, dtype=dtype, device=device),
    )


def test_every_gate_matrix_equals_numpy(rng: np.random.Generator) -> None:
    ref = torch.zeros(1, dtype=torch.float64)
    for name in sorted(GATE_NAMES - TWO_QUBIT):
        if name in np_gates.PARAMETRIC:
            a = rng.uniform(-7, 7, (5, np_gates.ANGLE_COUNT[name]))
            expected = np_gates.PARAMETRIC[name](a if name == "rot" else a[:, 0])
            got = gate_matrices(name, torch.as_tensor(a), ref)
        else:
            expected, got = np_gates.CONSTANT[name][None], gate_matrices(name, None, ref)
        np.testing.assert_allclose(got.numpy(), expected, atol=1e-15, err_msg=name)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 6])
def test_statevector_equals_numpy_on_random_circuits(n: int, rng: np.random.Generator) -> None:
    for _ in range(3):
        circ = random_all_gates_circuit(rng, n, 7)
        template, x, w = circ.as_template()
        ours = TorchCircuit(template).statevector(*_tensors(x, w))
        assert ours.dtype == torch.complex128
        np.testing.assert_allclose(ours.numpy(), statevector(circ), atol=1e-12)


@pytest.mark.parametrize("channel", list(CHANNELS))
def test_density_matrix_equals_numpy_with_every_channel(
    channel: str, rng: np.random.Generator
) -> None:
    for n in (1, 3, 4):
        circ = random_all_gates_circuit(rng, n, 5, n_gates=20)
        template, x, w = circ.as_template()
        noise = NoiseSpec(channel, float(rng.uniform(0.05, 0.95)), readout=0.07)
        sim = TorchCircuit(template, noise)
        rho = sim.density_matrix(*_tensors(x, w))
        np.testing.assert_allclose(rho.numpy(), density_matrix(circ, noise), atol=1e-12)
        np.testing.assert_allclose(
            sim.probabilities(*_tensors(x, w)).numpy(), probabilities(circ, noise), atol=1e-12
        )


def test_noise_free_density_matrix_is_the_pure_state(rng: np.random.Generator) -> None:
    circ = random_all_gates_circuit(rng, 3, 4)
    template, x, w = circ.as_template()
    rho = TorchCircuit(template).density_matrix(*_tensors(x, w)).numpy()
    np.testing.assert_allclose(rho, density_matrix(circ), atol=1e-12)


def test_eight_qubits_and_the_limit(rng: np.random.Generator) -> None:
    circ = random_all_gates_circuit(rng, MAX_QUBITS, 2, n_gates=40)
    template, x, w = circ.as_template()
    np.testing.assert_allclose(
        TorchCircuit(template).statevector(*_tensors(x, w)).numpy(), statevector(circ), atol=1e-12
    )
    with pytest.raises(ParameterError, match="num_qubits=9 is invalid: 1 to 8 qubits"):
        TorchCircuit(TemplateBuilder(9).build())


def test_eight_noisy_qubits_equal_aer(rng: np.random.Generator) -> None:
    # the NumPy density-matrix reference is too slow at 8 qubits (full 256 x 256 einsums)
    pytest.importorskip("qiskit_aer")
    from qdcnn.quantum.qiskit_bridge import run_aer

    circ = random_all_gates_circuit(rng, MAX_QUBITS, 3, n_gates=20)
    template, x, w = circ.as_template()
    noise = NoiseSpec("amplitude-damping", 0.2)
    np.testing.assert_allclose(
        TorchCircuit(template, noise).probabilities(*_tensors(x, w)).numpy(),
        run_aer(circ, noise=noise),
        atol=1e-9,
    )


def test_statevector_and_noisy_probabilities_equal_aer(rng: np.random.Generator) -> None:
    pytest.importorskip("qiskit_aer")
    from qdcnn.quantum.qiskit_bridge import run_aer, to_qiskit

    circ = random_all_gates_circuit(rng, 3, 6, n_gates=15)
    template, x, w = circ.as_template()
    aer = pytest.importorskip("qiskit_aer")
    sim = aer.AerSimulator(method="statevector")
    qcs = to_qiskit(circ)
    for qc in qcs:
        qc.save_statevector()
    result = sim.run(qcs).result()
    ours = TorchCircuit(template).statevector(*_tensors(x, w)).numpy()
    for i in range(len(qcs)):
        np.testing.assert_allclose(ours[i], np.asarray(result.get_statevector(i)), atol=1e-9)
    for channel in CHANNELS:
        noise = NoiseSpec(channel, 0.2)
        got = TorchCircuit(template, noise).probabilities(*_tensors(x, w)).numpy()
        np.testing.assert_allclose(got, run_aer(circ, noise=noise), atol=1e-9, err_msg=channel)


def _shift_gradient(f, params: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    grad = np.zeros_like(params)
    for k in range(params.size):
        up, down = params.copy(), params.copy()
        up.flat[k] += np.pi / 2
        down.flat[k] -= np.pi / 2
        grad.flat[k] = (f(up) - f(down)) / 2
    return grad


def test_gradients_equal_the_parameter_shift_rule(rng: np.random.Generator) -> None:
    n, layers = 3, 2
    sim = TorchCircuit(head_template(n, layers))
    x = rng.uniform(-np.pi, np.pi, (4, n))
    w = rng.uniform(-np.pi, np.pi, 3 * layers * n)
    coef = rng.normal(size=(4, n))

    def loss(xv: np.ndarray, wv: np.ndarray) -> float:
        with torch.no_grad():
            return float((sim.expectations(*_tensors(xv, wv)) * torch.as_tensor(coef)).sum())

    xt, wt = _tensors(x, w)
    xt.requires_grad_(True)
    wt.requires_grad_(True)
    (sim.expectations(xt, wt) * torch.as_tensor(coef)).sum().backward()
    np.testing.assert_allclose(
        wt.grad.numpy(), _shift_gradient(lambda v: loss(x, v), w), atol=1e-12
    )
    np.testing.assert_allclose(
        xt.grad.numpy(), _shift_gradient(lambda v: loss(v, w), x), atol=1e-12
    )


def test_gradients_of_every_angle_gate_equal_the_shift_rule(rng: np.random.Generator) -> None:
    # each angle is its own parameter; RX, RY, RZ, P and the three Rot angles obey the rule
    circ = random_all_gates_circuit(rng, 3, 1, n_gates=25)
    template, x, w = circ.as_template()
    params = np.concatenate([x.ravel(), w])
    split = x.size
    sim = TorchCircuit(template)
    probe = rng.normal(size=8)

    def f(v: np.ndarray) -> float:
        with torch.no_grad():
            p = sim.probabilities(*_tensors(v[None, :split], v[split:]))
        return float(p[0] @ torch.as_tensor(probe))

    xt, wt = _tensors(x, w)
    xt.requires_grad_(True)
    wt.requires_grad_(True)
    (sim.probabilities(xt, wt)[0] @ torch.as_tensor(probe)).backward()
    autograd = np.concatenate([xt.grad.numpy().ravel(), wt.grad.numpy()])
    np.testing.assert_allclose(autograd, _shift_gradient(f, params), atol=1e-12)


@pytest.mark.parametrize("channel", ["depolarizing", "amplitude-damping", "phase-damping-paper"])
def test_noisy_gradients_equal_finite_differences(channel: str, rng: np.random.Generator) -> None:
    n, layers = 3, 2
    sim = TorchCircuit(head_template(n, layers, reupload=True), NoiseSpec(channel, 0.15))
    x = rng.uniform(-np.pi, np.pi, (3, n))
    w = rng.uniform(-np.pi, np.pi, 3 * layers * n)
    xt, wt = _tensors(x, w)
    xt.requires_grad_(True)
    wt.requires_grad_(True)
    sim.expectations(xt, wt).sum().backward()

    def loss(v: np.ndarray) -> float:  # v = x and w flattened together
        with torch.no_grad():
            return float(
                sim.expectations(*_tensors(v[: x.size].reshape(x.shape), v[x.size :])).sum()
            )

    v, h = np.concatenate([x.ravel(), w]), 1e-6
    fd = np.array([(loss(v + h * e) - loss(v - h * e)) / (2 * h) for e in np.eye(v.size)])
    autograd = np.concatenate([xt.grad.numpy().ravel(), wt.grad.numpy()])
    np.testing.assert_allclose(autograd, fd, atol=1e-7)


def test_complex64_within_1e5_of_complex128(rng: np.random.Generator) -> None:
    circ = random_all_gates_circuit(rng, 4, 6)
    template, x, w = circ.as_template()
    noise = NoiseSpec("depolarizing", 0.1)
    for sim in (TorchCircuit(template), TorchCircuit(template, noise)):
        single = sim.probabilities(*_tensors(x, w, torch.float32))
        double = sim.probabilities(*_tensors(x, w))
        assert single.dtype == torch.float32
        np.testing.assert_allclose(single.numpy(), double.numpy(), atol=1e-5)
    psi = TorchCircuit(template).statevector(*_tensors(x, w, torch.float32))
    assert psi.dtype == torch.complex64
    np.testing.assert_allclose(psi.numpy(), statevector(circ), atol=1e-5)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_cuda_follows_the_input_device(rng: np.random.Generator) -> None:
    circ = random_all_gates_circuit(rng, 4, 6)
    template, x, w = circ.as_template()
    noise = NoiseSpec("amplitude-damping", 0.1, readout=0.05)
    for sim, expected in (
        (TorchCircuit(template), probabilities(circ)),
        (TorchCircuit(template, noise), probabilities(circ, noise)),
    ):
        xt, wt = _tensors(x, w, device="cuda")
        wt.requires_grad_(True)
        p = sim.probabilities(xt, wt)
        assert p.device.type == "cuda"
        np.testing.assert_allclose(p.detach().cpu().numpy(), expected, atol=1e-12)
        p.sum().backward()
        assert wt.grad is not None and wt.grad.device.type == "cuda"


def test_batched_equals_one_at_a_time(rng: np.random.Generator) -> None:
    sim = TorchCircuit(head_template(4, 2), NoiseSpec("bit-flip", 0.1))
    x = torch.as_tensor(rng.uniform(-3, 3, (5, 4)))
    w = torch.as_tensor(rng.uniform(-3, 3, 24))
    batched = sim.probabilities(x, w)
    for i in range(5):
        np.testing.assert_allclose(batched[i].numpy(), sim.probabilities(x[i], w)[0].numpy())


def test_shots_have_the_circuit_statistics(rng: np.random.Generator) -> None:
    sim = TorchCircuit(head_template(2, 1))
    x = torch.as_tensor(rng.uniform(-3, 3, (200, 2)))
    w = torch.as_tensor(rng.uniform(-3, 3, 6))
    exact = sim.probabilities(x, w)
    est = sim.probabilities(x, w, shots=4096, rng=3)
    again = sim.probabilities(x, w, shots=4096, rng=3)
    assert torch.equal(est, again)  # seeded
    np.testing.assert_allclose(est.sum(1).numpy(), 1.0)
    sigma = torch.sqrt(exact * (1 - exact) / 4096)
    assert bool(((est - exact).abs() <= 4.5 * sigma + 1e-12).all())
    assert not torch.equal(est, exact)


class _CrossTalk:
    """Device-like noise: after each gate, a 2-qubit depolarizing on (0, 1) and a bit flip on 2."""

    def channels_after(self, gate: Gate) -> list[tuple[tuple[int, ...], np.ndarray]]:
        two = np.einsum("aij,bkl->abikjl", depolarizing(0.2), depolarizing(0.2)).reshape(16, 4, 4)
        flip = np.stack([np.sqrt(0.9) * np.eye(2), np.sqrt(0.1) * np_gates.X])
        return [((0, 1), two), ((2,), flip)]


def _reference_density(circ, noise) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Gate by gate on full matrices, with the channels noise.channels_after names."""
    from qdcnn.quantum.simulator import _gate_unitary

    n = circ.num_qubits
    rho = np.zeros((circ.batch_size, 2**n, 2**n), dtype=complex)
    rho[:, 0, 0] = 1
    for g in circ.gates:
        u = _gate_unitary(g, n)
        rho = u @ rho @ np.conj(np.swapaxes(u, 1, 2))
        for qubits, kraus in noise.channels_after(Gate(g.name, g.qubits)):
            if len(qubits) == 1:
                full = embed(kraus, qubits[0], n)
            else:  # (0, 1): the low two bits of the index, qubit 0 least significant
                full = np.stack([np.kron(np.eye(2 ** (n - 2)), k) for k in kraus])
            rho = np.einsum("kij,bjl,kml->bim", full, rho, full.conj())
    return rho


def test_noise_objects_with_channels_after_plug_in(rng: np.random.Generator) -> None:
    noise = _CrossTalk()
    assert len(gate_channels(noise, Gate("ry", (2,)))) == 2
    assert [q for q, _ in gate_channels(NoiseSpec("bit-flip", 0.1), Gate("cx", (2, 0)))] == [
        (2,),
        (0,),
    ]
    circ = random_all_gates_circuit(rng, 3, 4, n_gates=12)
    template, x, w = circ.as_template()
    rho = TorchCircuit(template, noise).density_matrix(*_tensors(x, w)).numpy()
    np.testing.assert_allclose(rho, _reference_density(circ, noise), atol=1e-12)


@pytest.mark.parametrize(
    ("inputs", "weights", "message"),
    [
        (None, torch.zeros(6), "inputs=None is invalid: a tensor of shape"),
        (torch.zeros(2, 3), torch.zeros(6), r"inputs='shape \(2, 3\)' is invalid"),
        (torch.zeros(2, 2, dtype=torch.int64), torch.zeros(6), "a float32 or float64 torch"),
        (torch.zeros(2, 2), torch.zeros(6, dtype=torch.float64), "one dtype and one device"),
        (torch.zeros(2, 2), torch.zeros(3, 6), r"inputs/weights=\[2, 3\] is invalid"),
    ],
)
def test_bad_parameters(inputs, weights, message: str) -> None:  # type: ignore[no-untyped-def]
    sim = TorchCircuit(head_template(2, 1))
    with pytest.raises(ParameterError, match=message):
        sim.statevector(inputs, weights)


def test_shared_parameters_only_and_builder_circuits() -> None:
    # a circuit with no per-sample angle still runs (batch 1), here a Bell pair
    template, x, w = CircuitBuilder(2, 1).h(0).cx(0, 1).build().as_template()
    psi = TorchCircuit(template).statevector(*_tensors(x, w))
    np.testing.assert_allclose(psi.numpy(), [[2**-0.5, 0, 0, 2**-0.5]], atol=1e-15)


def test_device_noise_is_refused_with_where_it_runs() -> None:
    pytest.importorskip("qiskit_ibm_runtime")
    from qdcnn.errors import ParameterError
    from qdcnn.quantum.noise_text import parse_noise
    from qdcnn.quantum.templates import head_template
    from qdcnn.quantum.torchsim.program import compile_template

    with pytest.raises(ParameterError, match="device noise runs on the NumPy density-matrix"):
        compile_template(head_template(2, 1), parse_noise("device:FakeManilaV2"))


def test_readout_error_comes_through_the_noise_protocol() -> None:
    from qdcnn.quantum.noise import NoiseSpec
    from qdcnn.quantum.torchsim.program import readout_confusions

    class Asymmetric:
        def readout_matrices(self, n: int) -> list[np.ndarray]:
            return [np.array([[0.9, 0.2], [0.1, 0.8]])] * n

    assert readout_confusions(NoiseSpec(readout=0.0), 2) is None
    got = readout_confusions(Asymmetric(), 3)
    assert got is not None and len(got) == 3 and got[0][1, 0] == pytest.approx(0.1)
