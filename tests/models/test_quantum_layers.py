"""Quantum layers against PennyLane, the NumPy simulator, Aer and the shadow detector."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

torch = pytest.importorskip("torch")

from qdcnn.config import ShadowConfig  # noqa: E402
from qdcnn.data.synthetic import generate_scene  # noqa: E402
from qdcnn.errors import ParameterError  # noqa: E402
from qdcnn.models.quantum_layers import (  # noqa: E402
    QuantumHead,
    Quanvolution2d,
    RingMLPHead,
    UUConv2d,
    uu_block_scores,
)
from qdcnn.quantum.noise import NoiseSpec  # noqa: E402
from qdcnn.quantum.templates import (  # noqa: E402
    entangler_ranges,
    head_circuit,
    head_readout,
    uu_fidelity_template,
)
from qdcnn.quantum.torchsim import TorchCircuit  # noqa: E402
from qdcnn.vision.shadows import detect_shadows_uu  # noqa: E402


@pytest.fixture(autouse=True)
def _one_torch_thread():  # type: ignore[no-untyped-def]
    """Small tensors: a second intra-op thread only adds contention on a shared machine."""
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


def _head(n: int, layers: int, reupload: bool = False, noise=None, entangler="cx") -> QuantumHead:  # type: ignore[no-untyped-def]
    """The undressed head: its uniform random layer angles exercise the whole circuit."""
    torch.manual_seed(n + 10 * layers)
    return QuantumHead(
        5, n, layers, reupload=reupload, noise=noise, dressed=False, entangler=entangler
    ).double()


def _pennylane_head(n: int, layers: int, reupload: bool, entangler: str = "cx"):  # type: ignore[no-untyped-def]
    qml = pytest.importorskip("pennylane")
    dev = qml.device("default.qubit", wires=n)
    gate = {"cx": qml.CNOT, "cz": qml.CZ}[entangler]

    @qml.qnode(dev, interface="torch", diff_method="backprop")
    def circuit(x, w):  # type: ignore[no-untyped-def]
        if not reupload:
            qml.AngleEmbedding(x, wires=range(n), rotation="Y")
            qml.StronglyEntanglingLayers(w, wires=range(n), imprimitive=gate)
        else:
            for layer, r in enumerate(entangler_ranges(n, layers)):
                qml.AngleEmbedding(x, wires=range(n), rotation="Y")
                qml.StronglyEntanglingLayers(
                    w[layer : layer + 1], wires=range(n), ranges=[r], imprimitive=gate
                )
        return [qml.expval(qml.PauliZ(i)) for i in range(n)]

    return circuit


@pytest.mark.parametrize(
    ("n", "layers", "reupload", "entangler"),
    [
        (1, 2, False, "cx"),
        (2, 1, False, "cx"),
        (3, 3, False, "cx"),
        (4, 2, False, "cx"),
        (4, 2, True, "cx"),
        (3, 3, True, "cx"),
        (4, 2, False, "cz"),
        (3, 3, True, "cz"),
    ],
)
def test_head_circuit_equals_pennylane_values_and_gradients(
    n: int, layers: int, reupload: bool, entangler: str
) -> None:
    head = _head(n, layers, reupload, entangler=entangler)
    emb = torch.randn(6, 5, dtype=torch.float64)
    x = head.angles(emb).detach().requires_grad_(True)
    w = head.weights.detach().clone().requires_grad_(True)
    ours = head.circuit.expectations(x, w.reshape(-1))
    pl = torch.stack(list(_pennylane_head(n, layers, reupload, entangler)(x, w)), dim=-1)
    np.testing.assert_allclose(ours.detach().numpy(), pl.detach().numpy(), atol=1e-12)
    coef = torch.randn(6, n, dtype=torch.float64)
    g_ours = torch.autograd.grad((ours * coef).sum(), (x, w))
    g_pl = torch.autograd.grad((pl * coef).sum(), (x, w))
    for a, b in zip(g_ours, g_pl, strict=True):
        np.testing.assert_allclose(a.numpy(), b.numpy(), atol=1e-10)


def test_head_forward_is_projection_circuit_readout_and_trains() -> None:
    head = _head(4, 2)
    emb = torch.randn(8, 5, dtype=torch.float64)
    angles = math.pi * torch.tanh(head.projection(emb))
    z = head.circuit.expectations(angles, head.weights.reshape(-1))
    expected = head.readout(head.readout_gain * z)
    np.testing.assert_allclose(head(emb).detach().numpy(), expected.detach().numpy())
    assert float(angles.detach().abs().max()) < math.pi
    head(emb).sum().backward()
    for p in (head.projection.weight, head.weights, head.readout.weight):
        assert p.grad is not None and float(p.grad.abs().sum()) > 0


def test_head_under_noise_equals_numpy_density_matrix() -> None:
    noise = NoiseSpec("depolarizing", 0.1, readout=0.02)
    head = _head(3, 2, reupload=True, noise=noise)
    emb = torch.randn(4, 5, dtype=torch.float64)
    x = head.angles(emb).detach()
    ref = head_readout(x.numpy(), head.weights.detach().numpy(), reupload=True, noise=noise)[
        "expectations"
    ]
    np.testing.assert_allclose(head.expectations(emb).detach().numpy(), ref, atol=1e-12)


def test_head_shots_only_in_eval_mode() -> None:
    torch.manual_seed(0)
    head = QuantumHead(5, 2, 1, shots=512, shot_seed=4, dressed=False).double()
    emb = torch.randn(300, 5, dtype=torch.float64)
    exact = head.circuit.expectations(head.angles(emb), head.weights.reshape(-1)).detach()
    np.testing.assert_allclose(head.expectations(emb).detach().numpy(), exact.numpy())
    head.eval()
    est = head.expectations(emb).detach()
    # <Z> from 512 shots: standard deviation sqrt(1 - <Z>^2) / sqrt(512)
    sigma = torch.sqrt(1 - exact.square()) / math.sqrt(512)
    assert not torch.equal(est, exact)
    assert bool(((est - exact).abs() <= 4.5 * sigma + 1e-12).all())


@pytest.mark.parametrize("entangler", ["cx", "cz"])
def test_exported_head_circuit_on_aer_equals_qdcnn(tmp_path: Path, entangler: str) -> None:
    pytest.importorskip("qiskit_qasm3_import")
    aer = pytest.importorskip("qiskit_aer")
    from qdcnn.quantum.export import draw_text, from_qasm3, write_qasm3

    head = _head(4, 2, reupload=True, entangler=entangler)
    emb = torch.randn(3, 5, dtype=torch.float64)
    circuits = head.circuits(emb)
    assert any(g.name == entangler for g in circuits.gates)
    readout = head_readout(
        head.angles(emb).detach().numpy(),
        head.weights.detach().numpy(),
        reupload=True,
        entangler=entangler,
    )
    torch_z = head.expectations(emb).detach().numpy()
    np.testing.assert_allclose(readout["expectations"], torch_z, atol=1e-12)
    assert "U(" in draw_text(circuits, 1) or "rot(" in draw_text(circuits, 1)
    sim = aer.AerSimulator(method="statevector")
    for i in range(3):
        qc = from_qasm3(write_qasm3(circuits, tmp_path / f"head{i}.qasm", i).read_text())
        qc = qc.remove_final_measurements(inplace=False)
        qc.save_probabilities()
        probs = np.asarray(sim.run(qc).result().data(0)["probabilities"])
        np.testing.assert_allclose(probs, readout["probabilities"][i], atol=1e-9)
        z = [(probs * (1 - 2 * ((np.arange(16) >> q) & 1))).sum() for q in range(4)]
        np.testing.assert_allclose(z, torch_z[i], atol=1e-9)


def test_head_circuit_weight_order_is_pennylane_shape() -> None:
    w = np.arange(24, dtype=float).reshape(2, 4, 3) / 10
    flat = head_circuit(np.zeros(4), w.ravel())
    shaped = head_circuit(np.zeros(4), w)
    assert flat.params_of(0) == shaped.params_of(0)
    rots = [p for g, p in zip(flat.gates, flat.params_of(0), strict=True) if g.name == "rot"]
    assert rots[5] == tuple(w[1, 1])  # layer 1, qubit 1
    with pytest.raises(ParameterError, match="weights='shape"):
        head_circuit(np.zeros(4), np.zeros(10))


def test_classical_twin_has_the_same_parameter_count() -> None:
    for n, layers, features in [(1, 1, 3), (4, 2, 10), (5, 3, 64), (8, 4, 100)]:
        q = QuantumHead(features, n, layers)
        c = RingMLPHead(features, n, layers)
        count = [sum(p.numel() for p in m.parameters() if p.requires_grad) for m in (q, c)]
        assert count[0] == count[1]
        assert c(torch.randn(2, features)).shape == (2, 3)


def test_uu_conv_closed_form_equals_the_simulated_circuit() -> None:
    torch.manual_seed(1)
    for channels in (1, 2):
        layer = UUConv2d(channels, 3, kernel_size=2).double()
        with torch.no_grad():
            layer.centroids.uniform_(0, math.pi)
        means = torch.rand(50, channels, dtype=torch.float64)
        scores = layer.scores(means)  # (50, 3)
        sim = TorchCircuit(uu_fidelity_template(channels))
        for k in range(3):
            p0 = sim.probabilities(-math.pi * means, layer.centroids[k].detach())[:, 0]
            np.testing.assert_allclose(scores[:, k].detach().numpy(), p0.numpy(), atol=1e-14)


def test_uu_conv_reproduces_the_shadow_detector_block_scores() -> None:
    scene = generate_scene("track2", seed=3)
    for centroid in (70.0, 112.5):
        det = detect_shadows_uu(scene.image, ShadowConfig(centroid=centroid, shots=None))
        layer = UUConv2d.from_centroid(centroid).double()
        ours = uu_block_scores(layer, scene.image)
        assert ours.shape == (1, *det.block_scores.shape) == (1, 40, 79)
        np.testing.assert_allclose(ours[0], det.block_scores, atol=1e-12)


def test_uu_conv_forward_is_the_block_test_on_a_uniform_grid() -> None:
    scene = generate_scene("track1", seed=5, width=64, height=64)
    layer = UUConv2d.from_centroid(90.0, kernel_size=4).double()
    grey = torch.as_tensor(cv2.cvtColor(scene.image, cv2.COLOR_RGB2GRAY) / 255.0)
    conv = layer(grey[None, None])[0]
    blocks = uu_block_scores(layer, scene.image, downsample=1, grid=16)
    np.testing.assert_allclose(conv.detach().numpy(), blocks, atol=1e-12)
    det = detect_shadows_uu(
        scene.image, ShadowConfig(centroid=90.0, shots=None, downsample=1, grid=16)
    )
    np.testing.assert_allclose(conv[0].detach().numpy(), det.block_scores, atol=1e-12)


def test_uu_conv_trains_its_centroids_and_checks_input() -> None:
    layer = UUConv2d(2, 4, kernel_size=3, stride=1, padding=1)
    x = torch.rand(2, 2, 12, 16)
    out = layer(x)
    assert out.shape == (2, 4, 12, 16)
    out.sum().backward()
    assert layer.centroids.grad is not None and layer.centroids.grad.abs().sum() > 0
    with pytest.raises(ParameterError, match=r"x='shape \(2, 3, 12, 16\)' is invalid"):
        layer(torch.rand(2, 3, 12, 16))
    with pytest.raises(ParameterError, match="in_channels=3 is invalid"):
        UUConv2d(3)


def test_uu_conv_shots_in_eval_mode() -> None:
    layer = UUConv2d.from_centroid(100.0, kernel_size=2, shots=1024, shot_seed=1).double()
    x = torch.rand(1, 1, 40, 40, dtype=torch.float64)
    exact = layer(x)
    layer.eval()
    est = layer(x)
    sigma = torch.sqrt(exact * (1 - exact) / 1024)
    assert not torch.equal(est, exact)
    assert bool(((est - exact).abs() <= 4.5 * sigma + 1e-12).all())


def test_quanvolution_equals_the_simulator_and_pennylane() -> None:
    qml = pytest.importorskip("pennylane")
    layer = Quanvolution2d(in_channels=2, seed=7, weight_seed=3).double()
    image = torch.rand(2, 2, 6, 8, dtype=torch.float64)
    out = layer(image)
    assert out.shape == (2, 8, 3, 4)
    patches = layer.patches(image)  # (2, 2, 3, 4, 4)
    sim = layer.simulate(patches.reshape(-1, 4)).reshape(2, 2, 3, 4, 4)
    np.testing.assert_allclose(
        out.detach().numpy(), sim.permute(0, 1, 4, 2, 3).reshape(2, 8, 3, 4).numpy(), atol=1e-12
    )
    dev = qml.device("default.qubit", wires=4)
    weights = layer.weights.numpy()

    @qml.qnode(dev)
    def circuit(phi):  # type: ignore[no-untyped-def]  # PennyLane's quanvolution demo
        for j in range(4):
            qml.RY(np.pi * phi[j], wires=j)
        qml.RandomLayers(weights, wires=list(range(4)), seed=7)
        return [qml.expval(qml.PauliZ(j)) for j in range(4)]

    img = image[1, 0].numpy()
    j, k = 2, 4  # the patch at row 2, column 4 -> output position (1, 2)
    pl = circuit([img[j, k], img[j, k + 1], img[j + 1, k], img[j + 1, k + 1]])
    np.testing.assert_allclose(out[1, 0:4, 1, 2].detach().numpy(), np.array(pl), atol=1e-12)
    with pytest.raises(ParameterError, match="is invalid"):
        layer(torch.rand(1, 3, 4, 4))


def test_training_after_a_prediction_in_the_same_process() -> None:
    """Constants the simulator caches during a prediction (inference mode) can be trained with."""
    head = QuantumHead(5, n_qubits=3, n_layers=2, noise=NoiseSpec("depolarizing", 0.1))
    with torch.inference_mode():
        head(torch.randn(4, 5))
    fresh = QuantumHead(5, n_qubits=3, n_layers=2, noise=NoiseSpec("depolarizing", 0.1))
    loss = fresh(torch.randn(4, 5)).sum()
    loss.backward()
    assert fresh.weights.grad is not None and torch.isfinite(fresh.weights.grad).all()


# ---------------------------------------------------------------- the dressed heads (issue 20)


def _dressed(head_cls: type = QuantumHead, **kw) -> torch.nn.Module:  # type: ignore[no-untyped-def]
    torch.manual_seed(5)
    head = head_cls(5, 3, 2, **kw).double()
    with torch.no_grad():  # away from the starting values, so every term matters
        head.input_scale.copy_(torch.tensor([0.3, -0.4, 1.1]))
        head.output_scale.copy_(torch.tensor([1.5, 0.7, 2.0]))
        head.output_bias.copy_(torch.tensor([0.1, -0.2, 0.3]))
    return head


@pytest.mark.parametrize("head_cls", [QuantumHead, RingMLPHead])
def test_dressed_head_gradients_equal_finite_differences(head_cls: type) -> None:
    from torch.func import functional_call

    head = _dressed(head_cls)
    emb = torch.randn(4, 5, dtype=torch.float64)
    names = [n for n, _ in head.named_parameters()]
    params = tuple(p.detach().clone().requires_grad_(True) for p in head.parameters())

    def logits(*values: torch.Tensor) -> torch.Tensor:
        out: torch.Tensor = functional_call(head, dict(zip(names, values, strict=True)), (emb,))
        return out

    assert {"input_scale", "output_scale", "output_bias"} <= set(names)
    assert torch.autograd.gradcheck(logits, params, eps=1e-6, atol=1e-7)


def test_dressed_head_weight_gradients_equal_the_parameter_shift_rule() -> None:
    """Every layer angle enters one Pauli rotation (Rot = RZ RY RZ): the gradient of
    ``<Z_i>`` is half the difference of the circuit at the angle plus and minus pi / 2."""
    head = _dressed(reupload=True)
    emb = torch.randn(3, 5, dtype=torch.float64)
    coef = torch.randn(3, 3, dtype=torch.float64)
    x = head.angles(emb).detach()

    def objective(w: torch.Tensor) -> torch.Tensor:
        return (head.circuit.expectations(x, w.reshape(-1)) * coef).sum()

    w0 = head.weights.detach().clone().requires_grad_(True)
    (autograd,) = torch.autograd.grad(objective(w0), w0)
    shifted = torch.zeros_like(autograd)
    with torch.no_grad():
        for index in np.ndindex(*w0.shape):
            plus, minus = w0.detach().clone(), w0.detach().clone()
            plus[index] += math.pi / 2
            minus[index] -= math.pi / 2
            shifted[index] = (objective(plus) - objective(minus)) / 2
    np.testing.assert_allclose(autograd.numpy(), shifted.numpy(), atol=1e-12)


def test_dressed_head_is_bounded_scaled_and_starts_near_the_identity() -> None:
    torch.manual_seed(0)
    head = QuantumHead(5, 4, 2).double()
    assert head.dressed and float(head.weights.detach().abs().max()) < 0.05  # near identity
    assert torch.equal(head.output_scale, torch.ones(4, dtype=torch.float64))
    emb = torch.randn(16, 5, dtype=torch.float64) * 100  # saturates the projection
    shifted = head.angles(emb).detach() - math.pi / 2  # RY(pi / 2 + x): x bounded
    assert float(shifted.abs().max()) <= math.pi / 2 + 1e-9  # sigmoid(0) = 1/2
    with torch.no_grad():
        head.input_scale.fill_(50.0)
    assert float((head.angles(emb).detach() - math.pi / 2).abs().max()) <= math.pi
    z = head.expectations(emb)
    expected = head.readout(head.output_scale * z + head.output_bias)
    torch.testing.assert_close(head(emb), expected)
    # near the identity, <Z_i> follows the encoding: not constant over the batch
    spread = QuantumHead(5, 4, 2).double().expectations(emb[:8] / 100).detach().std(0)
    assert float(spread.min()) > 0.01
    twin = RingMLPHead(5, 4, 2)
    assert float((twin.layers.detach()[..., 0] - 1).abs().max()) < 0.05


def test_dressed_heads_keep_equal_parameter_counts() -> None:
    for n, layers, features in [(1, 1, 3), (4, 2, 10), (5, 3, 64)]:
        for reupload in (False, True):
            q = QuantumHead(features, n, layers, reupload=reupload)
            c = RingMLPHead(features, n, layers)
            count = [sum(p.numel() for p in m.parameters() if p.requires_grad) for m in (q, c)]
            assert count[0] == count[1]
            undressed = QuantumHead(features, n, layers, dressed=False)
            assert sum(p.numel() for p in undressed.parameters()) == count[0] - 3 * n


def test_product_ablation_has_no_entangling_gate_and_factorises() -> None:
    head = QuantumHead(5, 4, 3, entangle=False).double()
    assert not any(len(g.qubits) == 2 for g in head.circuit.template.gates)
    assert any(g.name == "cz" for g in QuantumHead(5, 4, 3).circuit.template.gates)
    emb = torch.randn(6, 5, dtype=torch.float64)
    circuits = head.circuits(emb)
    assert all(len(g.qubits) == 1 for g in circuits.gates)
    # a product state: each <Z_i> depends on its own angle only
    x = head.angles(emb).detach().requires_grad_(True)
    z = head.circuit.expectations(x, head.weights.reshape(-1))
    (jac,) = torch.autograd.grad(z[:, 0].sum(), x)
    assert float(jac[:, 1:].abs().max()) < 1e-12


def test_fixed_ablation_keeps_its_circuit_and_trains_the_rest() -> None:
    torch.manual_seed(0)
    head = QuantumHead(5, 3, 2, trainable_circuit=False, circuit_seed=7)
    again = QuantumHead(5, 3, 2, trainable_circuit=False, circuit_seed=7)
    assert torch.equal(head.weights, again.weights)  # seeded, not torch's global state
    assert "weights" in dict(head.named_buffers())
    assert "weights" not in dict(head.named_parameters())
    before = head.weights.clone()
    opt = torch.optim.AdamW(head.parameters(), lr=0.1)
    y = torch.arange(30) % 3
    for _ in range(3):
        opt.zero_grad()
        torch.nn.functional.cross_entropy(head(torch.randn(30, 5)), y).backward()
        opt.step()
    assert torch.equal(head.weights, before)
    assert head.readout.weight.grad is not None and head.projection.weight.grad is not None
    assert "weights" in head.state_dict()  # saved with the model


def test_dressed_cz_head_starts_at_the_identity_and_learns_entanglement() -> None:
    """With zero layer angles the CZ ring leaves every <Z_i> at the encoding's -sin(x_i)
    (a CX ring turns it into a parity of several qubits); the gradient of the second
    layer's angles then carries the neighbours' encodings, through the entanglement."""
    emb = torch.randn(8, 5, dtype=torch.float64)
    heads = {e: QuantumHead(5, 4, 2, entangler=e).double() for e in ("cz", "cx")}
    for head in heads.values():
        with torch.no_grad():
            head.weights.zero_()
            head.projection.load_state_dict(heads["cz"].projection.state_dict())
    x = heads["cz"].angles(emb) - math.pi / 2
    torch.testing.assert_close(heads["cz"].expectations(emb), -torch.sin(x))
    assert not torch.allclose(heads["cx"].expectations(emb), -torch.sin(x), atol=0.05)
    product = QuantumHead(5, 4, 2, entangle=False).double()
    with torch.no_grad():
        product.weights.zero_()
        product.projection.load_state_dict(heads["cz"].projection.state_dict())
    grads = [
        torch.autograd.grad(h.expectations(emb)[:, 0].sum(), h.weights)[0]
        for h in (heads["cz"], product)
    ]
    # layer 1's theta acts before any entangler: the same; layer 2's sees the CZ ring
    torch.testing.assert_close(grads[0][0, 0, 1], grads[1][0, 0, 1])
    assert abs(float(grads[0][1, 0, 1] - grads[1][1, 0, 1])) > 1e-2


def test_dressed_encoding_keeps_the_sign_of_the_projection() -> None:
    """From |0>, RY(pi/2 + x) gives <Z> = -sin(x): odd, so -x and x stay apart, and a
    saturated projection (x = +-pi/2) reads -+1, not 0 as cos(x) would."""
    head = QuantumHead(5, 3, 1, entangle=False).double()
    with torch.no_grad():
        head.weights.zero_()  # the identity layer
    emb = torch.randn(8, 5, dtype=torch.float64)
    x = head.angles(emb) - math.pi / 2
    torch.testing.assert_close(head.expectations(emb), -torch.sin(x))
    with torch.no_grad():
        head.projection.bias.zero_()
    torch.testing.assert_close(head.expectations(-emb), -head.expectations(emb))
