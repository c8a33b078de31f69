"""Quantum layers as ``torch.nn.Module``: a variational head, the UU-dagger convolution and
the quanvolution, all simulated exactly (and differentiably) by :mod:`qdcnn.quantum.torchsim`.

The circuits come from :mod:`qdcnn.quantum.templates`, the same definitions the NumPy
simulator, Qiskit, the drawings and the OpenQASM export use.

References
----------
.. [1] M. Schuld, A. Bocharov, K. Svore, N. Wiebe, "Circuit-centric quantum classifiers",
   Phys. Rev. A 101, 032308 (2020) (the StronglyEntanglingLayers ansatz).
.. [2] A. Perez-Salinas et al., "Data re-uploading for a universal quantum classifier",
   Quantum 4, 226 (2020).
.. [3] M. Henderson, S. Shakya, S. Pradhan, T. Cook, "Quanvolutional neural networks:
   powering image recognition with quantum circuits", Quantum Mach. Intell. 2, 2 (2020).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import require
from qdcnn._validation import (
    check_bool,
    check_float,
    check_int,
    check_optional_shots,
    check_shape,
    has_shape,
)
from qdcnn.errors import ParameterError
from qdcnn.quantum.circuits import CircuitBatch
from qdcnn.quantum.noise import NoiseSpec
from qdcnn.quantum.simulator import unitary
from qdcnn.quantum.templates import head_circuit, head_template, random_layers_template
from qdcnn.quantum.torchsim import MAX_QUBITS, TorchCircuit
from qdcnn.quantum.torchsim.measure import sampled, z_signs

require("torch", "the quantum layers")
import torch  # noqa: E402
import torch.nn.functional as F  # noqa: E402
from torch import nn  # noqa: E402

#: The legacy heads' fixed factor on their bounded features before the read-out
#: (``dressed=False``); the dressed heads start their trainable output scale at
#: :data:`OUTPUT_SCALE_INIT` instead (``docs/hybrid-collapse.md``).
READOUT_GAIN = 10.0
#: Initial value of the dressed heads' trainable per-feature output scale.
OUTPUT_SCALE_INIT = 1.0
#: Standard deviation of the dressed heads' near-identity initial layer angles.
NEAR_IDENTITY_STD = 0.01
#: The dressed quantum head encodes ``RY(pi / 2 + x_i)``: from ``|0>`` that is ``|+>`` then
#: ``RY(x_i)`` (the dressed circuit's Hadamard layer), so ``<Z_i> = -sin(x_i)`` near the
#: identity, odd in ``x_i``; ``RY(x_i)`` alone gives ``cos(x_i)``, which loses the sign of
#: the projection and is 0 wherever it saturates at ``+-pi / 2`` (docs/hybrid-collapse.md).
ENCODING_OFFSET = math.pi / 2


class _DressedHead(nn.Module):
    """What the quantum head and its twin share: the encoding and the read-out.

    ``dressed=True`` (Mari et al.'s dressed quantum circuit): angles
    ``x_i = pi sigmoid(s_i) tanh((W e + b)_i)``, a bounded trainable input scale starting at
    ``pi / 2``; the features ``f_i`` (``<Z_i>`` or the twin's) become ``g_i f_i + c_i`` with a
    trainable output scale ``g`` (starting at ``readout_gain``) and bias ``c`` per feature,
    then a linear read-out. ``dressed=False`` is the original head: ``x = pi tanh(W e + b)``
    and a fixed ``readout_gain`` on the features (files saved before the dressing load as it).
    """

    def __init__(self, in_features: int, n_qubits: int, readout_gain: float, dressed: bool):
        super().__init__()
        in_features = check_int("in_features", in_features, 1)
        self.readout_gain = check_float("readout_gain", readout_gain, 0.0, 1e3, open_lo=True)
        self.n_qubits = check_int("n_qubits", n_qubits, 1, MAX_QUBITS)
        self.dressed = check_bool("dressed", dressed)
        self.projection = nn.Linear(in_features, self.n_qubits)

    def _add_readout(self, num_classes: int) -> None:
        """The read-out (after the subclass's own parameters: legacy inits stay as they were)."""
        n = self.n_qubits
        self.readout = nn.Linear(n, check_int("num_classes", num_classes, 1))
        if self.dressed:
            self.input_scale = nn.Parameter(torch.zeros(n))
            self.output_scale = nn.Parameter(torch.full((n,), float(self.readout_gain)))
            self.output_bias = nn.Parameter(torch.zeros(n))

    def angles(self, embedding: torch.Tensor) -> torch.Tensor:
        """Encoded angles ``(B, n_qubits)``, in ``(-pi, pi)`` (see the class docstring)."""
        squashed = torch.tanh(self.projection(embedding))
        if not self.dressed:
            return math.pi * squashed
        return math.pi * torch.sigmoid(self.input_scale).to(squashed.dtype) * squashed

    def logits(self, features: torch.Tensor) -> torch.Tensor:
        """Class logits of the head's features ``(B, n_qubits)``."""
        if not self.dressed:
            out: torch.Tensor = self.readout(self.readout_gain * features)
            return out
        scale = self.output_scale.to(features.dtype)
        dressed: torch.Tensor = self.readout(scale * features + self.output_bias.to(features.dtype))
        return dressed

    def features(self, embedding: torch.Tensor) -> torch.Tensor:
        """The features the read-out sees before scaling, ``(B, n_qubits)``."""
        raise NotImplementedError

    def forward(self, embedding: torch.Tensor) -> torch.Tensor:
        """Logits ``(B, num_classes)`` for embeddings ``(B, in_features)``."""
        return self.logits(self.features(embedding))

    def diagnostics(self, embedding: torch.Tensor) -> dict[str, torch.Tensor]:
        """Encoded ``angles`` and read-out ``features`` (``<Z_i>``) of ``embedding``."""
        return {"angles": self.angles(embedding), "features": self.features(embedding)}


class QuantumHead(_DressedHead):
    """Embedding -> angles -> variational circuit -> ``<Z_i>`` -> class logits.

    The projection is a linear map of the embedding to ``n_qubits`` angles squashed
    to ``(-pi, pi)`` (:class:`_DressedHead`: a trainable bounded input scale when
    ``dressed``). Qubit ``i`` gets ``RY(x_i)``; then ``n_layers`` StronglyEntanglingLayers
    (``Rot(phi, theta, omega)`` on each qubit, then ``CX(i, (i + r) mod n)`` with
    ``r = (l mod (n - 1)) + 1``, or ``CZ`` on those pairs; none on one qubit), optionally
    re-uploading
    ``RY(x_i)`` before every layer [2]_. The read-out ``<Z_i>`` of every qubit goes,
    scaled (a trainable scale and bias per qubit when ``dressed``, else the fixed
    ``readout_gain``), through a linear map to the classes. Without re-uploading the
    circuit is exactly PennyLane's ``AngleEmbedding(rotation="Y")`` followed by
    ``StronglyEntanglingLayers``; ``weights`` has PennyLane's shape ``(n_layers, n_qubits, 3)``.
    Dressed, the weights start near the identity (normal, standard deviation
    :data:`NEAR_IDENTITY_STD`, from torch's seeded generator) and qubit ``i`` gets
    ``RY(pi / 2 + x_i)`` (:data:`ENCODING_OFFSET`), and the ring is of ``CZ``, so the
    whole circuit starts near the identity on ``<Z_i>`` (a ``CX`` ring would not:
    ``docs/hybrid-collapse.md``); undressed, the weights are uniform in ``[0, 2 pi)``
    (PennyLane's initialisation), the encoding is ``RY(x_i)`` and the ring is of ``CX``.

    Parameters
    ----------
    in_features : int
        Size of the embedding.
    n_qubits : int
        Qubits (1 to 8).
    n_layers : int
        Variational layers.
    reupload : bool
        Re-upload the encoding before every layer.
    shots : int or None
        ``None``: exact expectations. Otherwise, in evaluation mode (``model.eval()``),
        ``<Z_i>`` is estimated from this many measurements per sample (seeded by
        ``shot_seed``); training always uses the exact, differentiable values.
    noise : NoiseSpec or None
        Gate noise (and readout error): the circuit runs on the density matrix.
    num_classes : int
        Output logits.
    shot_seed : int
        Seed of the shot sampler.
    readout_gain : float
        Dressed: the initial output scale (:data:`OUTPUT_SCALE_INIT`). Undressed: the
        fixed factor on ``<Z_i>`` (:data:`READOUT_GAIN`, ``docs/readout-gain.md``).
    dressed : bool
        The dressed head (trainable input scale, output scale and bias, near-identity
        start), or the original one.
    entangle : bool
        ``False``: no entangling gates, a product state (the ``-noent`` ablation).
    entangler : {'cx', 'cz'} or None
        The ring's two-qubit gate; ``None``: ``'cz'`` dressed, ``'cx'`` undressed.
    trainable_circuit : bool
        ``False``: the layer angles are a fixed random draw (uniform in ``[0, 2 pi)``,
        seeded by ``circuit_seed``) kept as a buffer; only the encoding and the
        read-out train (the ``-fixed`` ablation).
    circuit_seed : int
        Seed of the fixed circuit's angles.
    """

    def __init__(
        self,
        in_features: int,
        n_qubits: int = 4,
        n_layers: int = 2,
        reupload: bool = False,
        shots: int | None = None,
        noise: NoiseSpec | None = None,
        num_classes: int = 3,
        shot_seed: int = 0,
        readout_gain: float | None = None,
        *,
        dressed: bool = True,
        entangle: bool = True,
        entangler: str | None = None,
        trainable_circuit: bool = True,
        circuit_seed: int = 0,
    ) -> None:
        gain = _default_gain(readout_gain, dressed)
        super().__init__(in_features, n_qubits, gain, dressed)
        self.n_layers = check_int("n_layers", n_layers, 1)
        self.reupload = check_bool("reupload", reupload)
        self.entangle = check_bool("entangle", entangle)
        # checked by the circuit template, built below (set_noise)
        self.entangler = ("cz" if self.dressed else "cx") if entangler is None else entangler
        self.shots = check_optional_shots(shots)
        self.noise = noise
        shape = (self.n_layers, self.n_qubits, 3)
        if not check_bool("trainable_circuit", trainable_circuit):
            gen = torch.Generator().manual_seed(check_int("circuit_seed", circuit_seed, 0))
            self.register_buffer("weights", torch.rand(shape, generator=gen) * (2 * math.pi))
        elif self.dressed:
            self.weights = nn.Parameter(torch.randn(shape) * NEAR_IDENTITY_STD)
        else:
            self.weights = nn.Parameter(torch.rand(shape) * (2 * math.pi))
        self._add_readout(num_classes)
        self._shot_rng = np.random.default_rng(shot_seed)
        self.set_noise(noise)

    def angles(self, embedding: torch.Tensor) -> torch.Tensor:
        """The ``RY`` angles ``(B, n_qubits)``: dressed, :data:`ENCODING_OFFSET` plus the
        bounded encoding (in ``(-pi / 2, 3 pi / 2)``); undressed, ``pi tanh(W e + b)``."""
        x = super().angles(embedding)
        return x + ENCODING_OFFSET if self.dressed else x

    def _template(self) -> Any:
        return head_template(self.n_qubits, self.n_layers, **self._circuit_options())

    def _circuit_options(self) -> dict[str, Any]:
        return {"reupload": self.reupload, "entangle": self.entangle, "entangler": self.entangler}

    def set_noise(self, noise: NoiseSpec | None) -> None:
        """Run the circuit under ``noise`` from now on (``None``: noise-free).

        Channel noise (:class:`~qdcnn.quantum.noise.NoiseSpec`) runs on the PyTorch
        density matrix and stays differentiable. A device's noise
        (:class:`~qdcnn.quantum.device.DeviceNoise`, which rewrites circuits into native
        gates) is simulated by the NumPy density-matrix simulator: evaluation only, no
        gradients.
        """
        self.noise = None if noise is None or noise.is_ideal else noise
        self._numpy_noise = getattr(self.noise, "device", None) is not None
        self.circuit = TorchCircuit(self._template(), None if self._numpy_noise else self.noise)

    def expectations(self, embedding: torch.Tensor) -> torch.Tensor:
        """``<Z_i>`` per qubit, ``(B, n_qubits)``: exact, or shot-estimated in eval mode."""
        x = self.angles(embedding)
        w = self.weights.reshape(-1).to(x.dtype)
        shots = None if self.training else self.shots
        if self._numpy_noise:
            return self._device_expectations(x, shots)
        return self.circuit.expectations(x, w, shots=shots, rng=self._shot_rng)

    features = expectations

    def _device_expectations(self, x: torch.Tensor, shots: int | None) -> torch.Tensor:
        from qdcnn.quantum.execute import run_probabilities
        from qdcnn.quantum.templates import z_expectations

        if self.training and torch.is_grad_enabled():
            raise ParameterError(
                "noise",
                "device" if self.noise is None else self.noise.label(),
                "channel noise to train under (device noise: eval only)",
            )
        circuits = head_circuit(
            x.detach().double().cpu().numpy(),
            self.weights.detach().double().cpu().numpy(),
            **self._circuit_options(),
        )
        probs = run_probabilities(circuits, shots=shots, noise=self.noise, rng=self._shot_rng)
        return torch.as_tensor(z_expectations(probs), dtype=x.dtype, device=x.device)

    def circuits(self, embedding: torch.Tensor) -> CircuitBatch:
        """The circuits this head runs for ``embedding``, for drawing and export."""
        with torch.no_grad():
            x = self.angles(embedding).double().cpu().numpy()
        w = self.weights.detach().double().cpu().numpy()
        return head_circuit(x, w, **self._circuit_options())


def _default_gain(readout_gain: float | None, dressed: bool) -> float:
    """The initial output scale (dressed) or the fixed gain (undressed) when none is given."""
    if readout_gain is not None:
        return readout_gain
    return OUTPUT_SCALE_INIT if dressed else READOUT_GAIN


class RingMLPHead(_DressedHead):
    """The classical twin of :class:`QuantumHead`, with the same number of parameters.

    The same encoding to ``n_qubits`` features and the same read-out (both dressed or
    both not: :class:`_DressedHead`); in place of the circuit, ``n_layers`` layers with the
    circuit's three parameters per qubit and its ring connectivity:
    ``y_i <- tanh(a_i y_i + c_i y_{(i + r) mod n} + b_i)`` with the layer's CNOT range
    ``r``. Dressed, the layers start near the identity like the circuit (``a = 1``,
    ``c = b = 0`` plus normal noise of :data:`NEAR_IDENTITY_STD`); undressed, ``a, c, b``
    are normal with standard deviation 0.5. The heads therefore differ only in the
    quantum circuit.
    """

    def __init__(
        self,
        in_features: int,
        n_qubits: int = 4,
        n_layers: int = 2,
        num_classes: int = 3,
        readout_gain: float | None = None,
        *,
        dressed: bool = True,
    ) -> None:
        from qdcnn.quantum.templates import entangler_ranges

        super().__init__(in_features, n_qubits, _default_gain(readout_gain, dressed), dressed)
        self.n_layers = check_int("n_layers", n_layers, 1)
        shape = (self.n_layers, self.n_qubits, 3)
        # a, c, b per layer and qubit (the circuit has phi, theta, omega)
        if self.dressed:
            start = torch.randn(shape) * NEAR_IDENTITY_STD
            start[..., 0] += 1.0
            self.layers = nn.Parameter(start)
        else:
            self.layers = nn.Parameter(torch.randn(shape) * 0.5)
        self.ranges = entangler_ranges(self.n_qubits, self.n_layers)
        self._add_readout(num_classes)

    def features(self, embedding: torch.Tensor) -> torch.Tensor:
        """The ring layers' output ``(B, n_qubits)``, in ``(-1, 1)``."""
        y = self.angles(embedding)
        for layer, r in zip(self.layers.unbind(0), self.ranges, strict=True):
            a, c, b = layer.unbind(-1)
            y = torch.tanh(a * y + c * torch.roll(y, -r, dims=1) + b)
        return y


class LinearHead(nn.Module):
    """The ``-linear`` ablation: one linear map of the embedding to the class logits.

    With the PilotNet trunk this is PilotNet itself (its last layer).
    """

    def __init__(self, in_features: int, num_classes: int = 3) -> None:
        super().__init__()
        self.readout = nn.Linear(
            check_int("in_features", in_features, 1), check_int("num_classes", num_classes, 1)
        )

    def forward(self, embedding: torch.Tensor) -> torch.Tensor:
        """Logits ``(B, num_classes)``."""
        out: torch.Tensor = self.readout(embedding)
        return out

    def diagnostics(self, embedding: torch.Tensor) -> dict[str, torch.Tensor]:
        """No angles nor bounded features: nothing to report."""
        return {}


def _shot_fidelity(scores: torch.Tensor, shots: int, rng: np.random.Generator) -> torch.Tensor:
    probs = torch.stack([scores, 1.0 - scores], dim=-1).clamp(0.0, 1.0)
    return sampled(probs.reshape(-1, 2), shots, rng)[:, 0].reshape(scores.shape)


class UUConv2d(nn.Module):
    """The paper's UU-dagger fidelity test as a convolution with trainable centroids.

    Each ``kernel_size x kernel_size`` patch mean ``v`` of every input channel (values in
    ``[0, 1]``: 8-bit values / 255) is encoded as ``RY(pi v)`` on one qubit per channel;
    output channel ``k`` is the fidelity ``|<C_k|T>|^2`` with the product state of the
    ``k``-th centroid's angles: ``prod_c cos^2((theta_kc - pi v_c) / 2)``, the
    probability of ``|0...0>`` after ``RY(theta_kc)`` then ``RY(-pi v_c)`` (paper Alg. 1;
    :func:`qdcnn.quantum.templates.uu_fidelity_template`). The closed form is what runs;
    the tests check it against the simulated circuit. Padded patches average only
    their real pixels.

    The paper's shadow detector is this layer with one channel (intensity), ``K = 1``,
    a fixed centroid and the detector's block grid (:func:`uu_block_scores`).

    Parameters
    ----------
    in_channels : {1, 2}
        Intensity, and chromaticity as a second channel.
    n_centroids : int
        Output channels ``K``.
    kernel_size, stride, padding : int
        As in ``nn.AvgPool2d`` (``stride`` defaults to ``kernel_size``).
    shots : int or None
        ``None``: exact fidelities; otherwise shot-estimated in evaluation mode.
    shot_seed : int
        Seed of the shot sampler.
    """

    def __init__(
        self,
        in_channels: int = 1,
        n_centroids: int = 1,
        kernel_size: int = 4,
        stride: int | None = None,
        padding: int = 0,
        shots: int | None = None,
        shot_seed: int = 0,
    ) -> None:
        super().__init__()
        self.in_channels = check_int("in_channels", in_channels, 1, 2)
        self.n_centroids = check_int("n_centroids", n_centroids, 1)
        self.kernel_size = check_int("kernel_size", kernel_size, 1)
        self.stride = self.kernel_size if stride is None else check_int("stride", stride, 1)
        self.padding = check_int("padding", padding, 0, self.kernel_size // 2)
        self.shots = check_optional_shots(shots)
        # centroid angles theta_kc, spread over [0, pi] (values 0..255)
        start = torch.linspace(0.15, 0.85, self.n_centroids) * math.pi
        self.centroids = nn.Parameter(start[:, None].repeat(1, self.in_channels).contiguous())
        self._shot_rng = np.random.default_rng(shot_seed)

    @classmethod
    def from_centroid(cls, value: float, **kwargs: Any) -> UUConv2d:
        """One intensity centroid at the 8-bit ``value`` (the paper's detector)."""
        layer = cls(1, 1, **kwargs)
        with torch.no_grad():
            layer.centroids.fill_(float(value) * math.pi / 255.0)
        return layer

    def scores(self, means: torch.Tensor) -> torch.Tensor:
        """Fidelities ``(B, K, ...)`` of patch means ``(B, C, ...)`` in ``[0, 1]``."""
        theta_x = means * math.pi
        shape = (1, self.n_centroids, self.in_channels) + (1,) * (means.ndim - 2)
        half = (self.centroids.to(means.dtype).view(shape) - theta_x.unsqueeze(1)) * 0.5
        out = torch.cos(half).square().prod(dim=2)
        if self.shots is not None and not self.training:
            out = _shot_fidelity(out, self.shots, self._shot_rng)
        return out

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, K, H', W')`` fidelities for ``(B, C, H, W)`` values in ``[0, 1]``."""
        check_shape("x", x, f"B,{self.in_channels},H,W", f"(B, {self.in_channels}, H, W) values")
        means = F.avg_pool2d(
            x, self.kernel_size, self.stride, self.padding, count_include_pad=False
        )
        return self.scores(means)


def uu_block_scores(
    layer: UUConv2d,
    image: NDArray[np.uint8],
    *,
    downsample: int = 4,
    grid: int = 79,
    feature: str = "intensity",
) -> NDArray[np.float64]:
    """``layer`` applied on the shadow detector's block grid of an RGB ``image``.

    The grid of :func:`qdcnn.vision.shadows.detect_shadows_uu` has blocks of unequal
    size (``round(linspace(...))`` edges), which no fixed convolution reproduces, so the
    block means come from :func:`qdcnn.vision.shadows.block_means` and the layer scores
    them. Returns the ``(K, rows, cols)`` fidelities (``K = 1``: the detector's scores).
    """
    from qdcnn.vision.shadows import block_grid, block_means, feature_input

    if layer.in_channels != 1:
        raise ParameterError("layer.in_channels", layer.in_channels, "1 (one feature map)")
    values = feature_input(image, feature)
    geometry = block_grid(values.shape[:2], downsample, grid)
    means = block_means(values, geometry, downsample) / 255.0
    ref = layer.centroids
    with torch.no_grad():
        scores = layer.scores(
            torch.as_tensor(means, dtype=ref.dtype, device=ref.device)[None, None]
        )
    return scores[0].double().cpu().numpy()


class Quanvolution2d(nn.Module):
    """Henderson et al.'s quanvolution [3]_: a fixed random 4-qubit circuit on 2x2 patches.

    As in PennyLane's quanvolution demo: the four pixels ``x`` of every 2x2 patch
    (stride 2; order top-left, top-right, bottom-left, bottom-right = qubits 0-3) are
    encoded as ``RY(pi x_j)``, then a seeded ``RandomLayers`` circuit (PennyLane's
    sampling, :func:`qdcnn.quantum.templates.random_layers_template`) with fixed random
    weights in ``[0, 2 pi)``, and ``<Z_j>`` of the four qubits are four output channels
    per input channel (channel ``4 c + j``). Nothing is trained.

    The circuit after the encoding is one fixed unitary ``U``, so ``<Z_j>`` is the
    quadratic form ``psi^T Re(U^dagger Z_j U) psi`` of the real product state ``psi``
    of the encoding; the tests check this against the simulated circuit and PennyLane.

    Parameters
    ----------
    in_channels : int
        Input channels (each is quanvolved separately).
    n_layers : int
        ``RandomLayers`` layers (four rotations each).
    seed : int
        Seed of the circuit's structure (PennyLane's ``RandomLayers(seed=...)``).
    weight_seed : int
        Seed of the fixed rotation angles.
    """

    n_qubits = 4
    weights: torch.Tensor
    observables: torch.Tensor

    def __init__(
        self, in_channels: int = 1, n_layers: int = 1, seed: int = 42, weight_seed: int = 0
    ) -> None:
        super().__init__()
        self.in_channels = check_int("in_channels", in_channels, 1)
        self.n_layers = check_int("n_layers", n_layers, 1)
        self.seed = int(seed)
        self.template = random_layers_template(4, self.n_layers, 4, seed=self.seed)
        weights = np.random.default_rng(weight_seed).uniform(0, 2 * np.pi, (self.n_layers, 4))
        self.register_buffer("weights", torch.as_tensor(weights))
        self.register_buffer("observables", torch.as_tensor(self._observables(weights)))

    def _observables(self, weights: NDArray[np.float64]) -> NDArray[np.float64]:
        """``Re(U^dagger Z_j U)`` for the four qubits, ``(4, 16, 16)``."""
        bound = self.template.bind(np.zeros(4), weights.ravel())
        layers = CircuitBatch(4, 1, bound.gates[4:], "random_layers")  # after the encoding
        u = unitary(layers)[0]
        z = z_signs(4, torch.zeros(1, dtype=torch.float64)).numpy()  # (16, 4)
        obs = np.einsum("ki,kj,kq->qij", u.conj(), u, z)
        return np.ascontiguousarray(obs.real)

    def patches(self, x: torch.Tensor) -> torch.Tensor:
        """The 2x2 patches ``(B, C, H/2, W/2, 4)`` of ``(B, C, H, W)`` (odd edges dropped)."""
        b, c, h, w = x.shape
        x = x[:, :, : h - h % 2, : w - w % 2]
        p = x.reshape(b, c, h // 2, 2, w // 2, 2).permute(0, 1, 2, 4, 3, 5)
        return p.reshape(b, c, h // 2, w // 2, 4)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, 4 C, H/2, W/2)`` expectations for ``(B, C, H, W)`` pixel values."""
        if not has_shape(x, f"B,{self.in_channels},H,W") or min(x.shape[2:]) < 2:
            raise ParameterError(
                "x", f"shape {tuple(x.shape)}", f"(B, {self.in_channels}, H >= 2, W >= 2)"
            )
        p = self.patches(x)
        half = p * (math.pi / 2)
        cos, sin = torch.cos(half), torch.sin(half)
        # RY(pi x)|0> = (cos, sin) per qubit; qubit 3 is the most significant bit
        psi = torch.stack([cos[..., 3], sin[..., 3]], -1)
        for q in (2, 1, 0):
            amp = torch.stack([cos[..., q], sin[..., q]], -1)
            psi = (psi[..., :, None] * amp[..., None, :]).flatten(-2)
        obs = self.observables.to(psi.dtype)
        z = torch.einsum("...i,qij,...j->...q", psi, obs, psi)  # (B, C, H/2, W/2, 4)
        b, c, h2, w2, _ = z.shape
        return z.permute(0, 1, 4, 2, 3).reshape(b, 4 * c, h2, w2)

    def simulate(self, patches: torch.Tensor) -> torch.Tensor:
        """``<Z_j>`` of patches ``(N, 4)`` through the gate-by-gate simulator (the reference)."""
        sim = TorchCircuit(self.template)
        w = self.weights.reshape(-1).to(patches.dtype)
        return sim.expectations(patches * math.pi, w)
