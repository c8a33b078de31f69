"""Run a compiled template on torch tensors: statevector or density matrix.

The only Python loops are over the steps of the circuit (and, inside a step, over
its rounds or qubits); every sample of the batch goes through each torch operation
together. Parameters that are 1-D (shared by the batch, e.g. trained weights) keep
the gates built from them batch-free: their matrices are built once and, in the
statevector simulation, a run of such gates on a full register is multiplied into
one ``2**n x 2**n`` unitary before it touches the states. Until the first two-qubit
gate the register is a product state, kept as one small vector per qubit.

Density matrices are simulated in the Pauli basis (:mod:`.pauli`): real
coefficients, a real ``4 x 4`` transfer matrix per qubit for each one-qubit gate
together with its noise, signed permutations for ``cx`` and ``cz``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from qdcnn._optional import require
from qdcnn._validation import check_shape
from qdcnn.errors import ParameterError
from qdcnn.quantum import gates as np_gates
from qdcnn.quantum.circuits import CircuitTemplate
from qdcnn.quantum.noise import GateNoise
from qdcnn.quantum.torchsim import pauli
from qdcnn.quantum.torchsim.gates import complex_dtype, gate_matrices
from qdcnn.quantum.torchsim.measure import (
    readout_matrix,
    sampled,
    state_probabilities,
    z_expectations,
)
from qdcnn.quantum.torchsim.program import Block, Channels, Monomial, Program, compile_template

require("torch", "the PyTorch quantum simulator")
import torch  # noqa: E402

from qdcnn.quantum.torchsim._constants import cached_constant, make_constant  # noqa: E402

#: Largest register whose batch-free gate runs are multiplied into one unitary.
_FUSE_UNITARY_MAX_QUBITS = 6


@dataclass(frozen=True)
class _Group:
    """The gates of one name built in one call, from shared or per-sample parameters."""

    name: str
    per_sample: bool
    gates: tuple[int, ...]
    slots: tuple[int, ...]


@dataclass(frozen=True)
class _RoundPlan:
    parts: tuple[tuple[int, tuple[int, ...]], ...]  # (group, positions in the group), in order
    positions: tuple[int, ...]  # where each gathered matrix goes in the block's qubit order
    gates: tuple[int, ...]


@dataclass(frozen=True)
class _BlockPlan:
    qubits: tuple[int, ...]  # block qubits in the order of the per-qubit tensors
    rounds: tuple[_RoundPlan, ...]
    per_sample: bool


@dataclass(frozen=True)
class _Plan:
    groups: tuple[_Group, ...]
    blocks: dict[int, _BlockPlan]  # step index -> plan


def _check_params(
    template: CircuitTemplate, inputs: torch.Tensor | None, weights: torch.Tensor | None
) -> tuple[torch.Tensor | None, torch.Tensor | None, int, torch.Tensor]:
    given = [t for t in (inputs, weights) if t is not None]
    for label, t, size in (
        ("inputs", inputs, template.num_inputs),
        ("weights", weights, template.num_weights),
    ):
        if t is None:
            if size:
                raise ParameterError(label, None, f"a tensor of shape ({size},) or (B, {size})")
            continue
        if not isinstance(t, torch.Tensor) or t.dtype not in (torch.float32, torch.float64):
            raise ParameterError(label, type(t).__name__, "a float32 or float64 torch tensor")
        check_shape(label, t, f"{size}|B,{size}", f"({size},) or (B, {size})")
    if not given:
        raise ParameterError("inputs/weights", None, "at least one tensor (for dtype and device)")
    ref = given[0]
    if any(t.dtype != ref.dtype or t.device != ref.device for t in given):
        raise ParameterError(
            "inputs/weights",
            [(str(t.dtype), str(t.device)) for t in given],
            "one dtype and one device",
        )
    rows = {t.shape[0] for t in given if t.ndim == 2}
    if len(rows) > 1:
        raise ParameterError("inputs/weights", sorted(rows), "one batch size")
    return inputs, weights, rows.pop() if rows else 1, ref


class TorchCircuit:
    """A template compiled for one noise model, run on batches of torch parameters.

    Parameters
    ----------
    template : CircuitTemplate
        The circuit, in the shared vocabulary of :mod:`qdcnn.quantum.circuits`.
    noise : NoiseSpec or None
        Gate noise (after every gate on every qubit it touches, as in
        :func:`qdcnn.quantum.simulator.density_matrix`) and readout error.

    Notes
    -----
    ``inputs`` ``(B, num_inputs)`` and ``weights`` ``(num_weights,)`` may each be 1-D
    (shared) or 2-D (one row per sample). float32 parameters give complex64
    amplitudes, float64 give complex128; the device is the parameters' device.
    Everything is differentiable with autograd, noise channels included.
    """

    def __init__(self, template: CircuitTemplate, noise: GateNoise | None = None) -> None:
        self.template = template
        self.noise = noise
        self.program: Program = compile_template(template, noise)
        self._plans: dict[tuple[bool, bool], _Plan] = {}
        self._consts: dict[tuple[Any, ...], Any] = {}

    @property
    def num_qubits(self) -> int:
        return self.template.num_qubits

    # ---- public entry points ---------------------------------------------------------

    def statevector(
        self, inputs: torch.Tensor | None = None, weights: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Final states ``(B, 2**n)`` (complex) from ``|0...0>``; gate noise is ignored."""
        psi = self._evolve_state(inputs, weights)
        return psi if psi.is_complex() else psi.to(complex_dtype(psi.dtype))

    def density_matrix(
        self, inputs: torch.Tensor | None = None, weights: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Final density matrices ``(B, 2**n, 2**n)`` with the gate noise."""
        if not self.program.noisy:
            psi = self.statevector(inputs, weights)
            return psi[:, :, None] * psi.conj()[:, None, :]
        c = self._evolve_density(inputs, weights)
        return pauli.density_matrix(c, self.num_qubits, complex_dtype(c.dtype))

    def probabilities(
        self,
        inputs: torch.Tensor | None = None,
        weights: torch.Tensor | None = None,
        *,
        shots: int | None = None,
        rng: int | np.random.Generator | None = None,
    ) -> torch.Tensor:
        """Outcome probabilities ``(B, 2**n)``, qubit 0 the least significant bit.

        With noise, from the density matrix, then the readout error. With ``shots``,
        estimated from that many measurements (seeded by ``rng``; not differentiable).
        """
        if self.program.noisy:
            probs = pauli.probabilities(self._evolve_density(inputs, weights), self.num_qubits)
        else:
            probs = state_probabilities(self._evolve_state(inputs, weights))
        if self.program.readout is not None:
            probs = probs @ readout_matrix(self.program.readout, probs).T
        return probs if shots is None else sampled(probs, shots, rng)

    def expectations(
        self,
        inputs: torch.Tensor | None = None,
        weights: torch.Tensor | None = None,
        *,
        shots: int | None = None,
        rng: int | np.random.Generator | None = None,
    ) -> torch.Tensor:
        """``<Z_q>`` of every qubit, shape ``(B, n)`` (from :meth:`probabilities`)."""
        probs = self.probabilities(inputs, weights, shots=shots, rng=rng)
        return z_expectations(probs, self.num_qubits)

    # ---- parameters and gate matrices --------------------------------------------------

    def _plan(self, inputs_batched: bool, weights_batched: bool) -> _Plan:
        key = (inputs_batched, weights_batched)
        if key not in self._plans:
            self._plans[key] = _make_plan(self.program, inputs_batched, weights_batched)
        return self._plans[key]

    def _matrices(
        self,
        plan: _Plan,
        inputs: torch.Tensor | None,
        weights: torch.Tensor | None,
        batch: int,
        ref: torch.Tensor,
    ) -> list[torch.Tensor]:
        """One tensor ``(1 or B, k, 2, 2)`` per group of gates."""
        t = self.template
        shared = full = None
        out = []
        for group in plan.groups:
            if not group.slots:
                m = gate_matrices(group.name, None, ref)
                out.append(m.unsqueeze(1).expand(1, len(group.gates), 2, 2))
                continue
            slots = group.slots
            if min(slots) >= t.num_inputs and weights is not None:  # weights alone
                source = weights if weights.ndim == 2 else weights[None]
                slots = tuple(k - t.num_inputs for k in slots)
            elif max(slots) < t.num_inputs and inputs is not None:  # inputs alone
                source = inputs if inputs.ndim == 2 else inputs[None]
            elif group.per_sample:
                if full is None:
                    full = _concat(t, inputs, weights, batch, ref)
                source = full
            else:
                if shared is None:
                    shared = _concat(t, _shared(inputs), _shared(weights), 1, ref)
                source = shared
            if slots != tuple(range(source.shape[1])):
                source = source.index_select(1, self._index(("slots", slots), slots, ref.device))
            count = np_gates.ANGLE_COUNT[group.name]
            angles = source.view(source.shape[0], len(group.gates), count)
            out.append(gate_matrices(group.name, angles, ref))
        return out

    def _index(self, key: Any, values: Any, device: torch.device) -> torch.Tensor:
        full_key = (key, device)
        if full_key not in self._consts:
            self._consts[full_key] = make_constant(
                lambda: torch.as_tensor(np.asarray(values), device=device)
            )
        out: torch.Tensor = self._consts[full_key]
        return out

    def _const(self, key: Any, make: Any, ref: torch.Tensor) -> Any:
        full_key = (key, ref.dtype, ref.device)
        if full_key not in self._consts:
            self._consts[full_key] = make_constant(make)
        return self._consts[full_key]

    def _round(self, rp: _RoundPlan, mats: list[torch.Tensor]) -> torch.Tensor:
        pieces = []
        for g, pos in rp.parts:
            m = mats[g]
            if pos != tuple(range(m.shape[1])):
                m = m.index_select(1, self._index(("pos", pos), pos, m.device))
            pieces.append(m)
        if len(pieces) == 1:
            return pieces[0]
        pieces = _common(pieces)
        return torch.cat(pieces, dim=1)

    def _fuse(self, bp: _BlockPlan, mats: list[torch.Tensor], columns: bool) -> torch.Tensor:
        """Per-qubit products of the block's gates: ``(B', m, 2, 2)`` (or first columns)."""
        first = self._round(bp.rounds[0], mats)
        acc = first[..., :1] if columns else first
        for rp in bp.rounds[1:]:
            acc = _apply_round(acc, self._round(rp, mats), rp.positions, self._index)
        return acc

    # ---- statevector ---------------------------------------------------------------

    def _evolve_state(
        self, inputs: torch.Tensor | None, weights: torch.Tensor | None
    ) -> torch.Tensor:
        inputs, weights, batch, ref = _check_params(self.template, inputs, weights)
        plan = self._plan(_batched(inputs), _batched(weights))
        mats = self._matrices(plan, inputs, weights, batch, ref)
        n = self.num_qubits
        product: dict[int, torch.Tensor] | None = {}  # qubit -> (B', 2) while unentangled
        psi: torch.Tensor | None = None
        pending: torch.Tensor | None = None  # a batch-free unitary not yet applied to psi
        for i, step in enumerate(self.program.steps):
            if isinstance(step, Block):
                bp = plan.blocks[i]
                if product is not None:
                    fused = self._fuse(bp, mats, columns=not product)
                    _product_update(product, bp.qubits, fused, 2, ref)
                    continue
                assert psi is not None
                fused = self._fuse(bp, mats, columns=False)
                if not bp.per_sample and n <= _FUSE_UNITARY_MAX_QUBITS:
                    u = _kron_unitary(fused[0], bp.qubits, n)
                    pending = u if pending is None else _matmul(u, pending)
                    continue
                if pending is not None:
                    psi, pending = _apply_unitary(psi, pending), None
                for q, m in zip(bp.qubits, fused.unbind(1), strict=True):
                    psi = _apply_1q(psi, m, q, n)
            elif isinstance(step, Monomial):
                if product is not None:
                    psi, product = _product_state(product, n, ref), None
                assert psi is not None
                perm = self._index(("perm", i), step.perm, ref.device)
                sign = (
                    None
                    if step.sign is None
                    else self._const(
                        ("sign", i),
                        lambda s=step.sign: torch.as_tensor(s, dtype=ref.dtype, device=ref.device),
                        ref,
                    )
                )
                if pending is not None:
                    pending = pending.index_select(0, perm)
                    pending = pending if sign is None else pending * sign[:, None]
                else:
                    psi = psi.index_select(1, perm)
                    psi = psi if sign is None else psi * sign
        if product is not None:
            psi = _product_state(product, n, ref)
        assert psi is not None
        if pending is not None:
            psi = _apply_unitary(psi, pending)
        return psi.expand(batch, -1) if psi.shape[0] != batch else psi

    # ---- density matrix (Pauli basis, real) -------------------------------------------

    def _noise_ptms(self, ref: torch.Tensor) -> list[torch.Tensor]:
        """Each distinct Kraus set as a real Pauli transfer matrix ``(4**m, 4**m)``."""

        def make() -> list[torch.Tensor]:
            return [
                torch.as_tensor(pauli.kraus_ptm(k), dtype=ref.dtype, device=ref.device)
                for k in self.program.kraus
            ]

        out: list[torch.Tensor] = self._const("noise-ptm", make, ref)
        return out

    def _round_noise(self, rp: _RoundPlan, ref: torch.Tensor) -> torch.Tensor | None:
        """``(k, 4, 4)`` noise transfer matrices after the round's gates (``None``: no noise)."""
        fused = self.program.fused_noise
        if not any(g in fused for g in rp.gates):
            return None

        def make() -> torch.Tensor:
            ptm = self._noise_ptms(ref)
            eye = torch.eye(4, dtype=ref.dtype, device=ref.device)
            mats = []
            for g in rp.gates:
                m = eye
                for k in fused.get(g, ()):
                    m = ptm[k] @ m
                mats.append(m)
            return torch.stack(mats)

        return self._const(("round-noise", rp.gates), make, ref)

    def _fuse_ptm(
        self, bp: _BlockPlan, mats: list[torch.Tensor], ref: torch.Tensor, columns: bool
    ) -> torch.Tensor:
        """Per-qubit transfer matrices ``(B', m, 4, 4)`` of gate-then-noise (or Bloch columns)."""

        def round_ptm(rp: _RoundPlan) -> torch.Tensor:
            u = self._round(rp, mats)
            r = pauli.unitary_ptm(u if u.is_complex() else u.to(complex_dtype(u.dtype)))
            noise = self._round_noise(rp, ref)
            return r if noise is None else noise @ r

        first = round_ptm(bp.rounds[0])
        zero = _zero_bloch(ref.dtype, ref.device)
        acc = first @ zero if columns else first
        for rp in bp.rounds[1:]:
            acc = _apply_round(acc, round_ptm(rp), rp.positions, self._index)
        return acc

    def _monomial_map(self, i: int, step: Monomial, device: torch.device, ref: torch.Tensor) -> Any:
        key = ("pauli-mono", i)
        if key not in self._consts:
            n = self.num_qubits
            mapping = None
            for g in step.gates:
                gate = self.template.gates[g]
                u = (np_gates.CX if gate.name == "cx" else np_gates.CZ).astype(np.complex128)
                m = pauli.clifford_map(u, gate.qubits, n)
                mapping = m if mapping is None else pauli.then(mapping, m)
            self._consts[key] = mapping
        src, sign = self._consts[key]
        src_t = self._index(("pauli-src", i), src, device)
        sign_t = self._const(
            ("pauli-sign", i),
            lambda: torch.as_tensor(sign[:, None], dtype=ref.dtype, device=device),
            ref,
        )
        return src_t, sign_t

    def _evolve_density(
        self, inputs: torch.Tensor | None, weights: torch.Tensor | None
    ) -> torch.Tensor:
        """Final states as real Pauli coefficients ``(4**n, B)`` (see :mod:`.pauli`)."""
        inputs, weights, batch, ref = _check_params(self.template, inputs, weights)
        plan = self._plan(_batched(inputs), _batched(weights))
        mats = self._matrices(plan, inputs, weights, batch, ref)
        n = self.num_qubits
        product: dict[int, torch.Tensor] | None = {}  # qubit -> Bloch vector (B', 4)
        c: torch.Tensor | None = None
        for i, step in enumerate(self.program.steps):
            if isinstance(step, Block):
                bp = plan.blocks[i]
                fused = self._fuse_ptm(bp, mats, ref, columns=product is not None and not product)
                if product is not None:
                    _product_update(
                        product, bp.qubits, fused, 4, ref, _zero_bloch(ref.dtype, ref.device)
                    )
                    continue
                assert c is not None
                for q, r in zip(bp.qubits, fused.unbind(1), strict=True):
                    c = pauli.apply_local(c, r[0] if r.shape[0] == 1 else r, q, n)
                continue
            if product is not None:
                c, product = self._bloch_product(product, ref), None
            assert c is not None
            if isinstance(step, Monomial):
                src, sign = self._monomial_map(i, step, ref.device, ref)
                c = c.index_select(0, src) * sign
            elif isinstance(step, Channels):
                ptm = self._noise_ptms(ref)
                for qubits, k in step.channels:
                    c = pauli.apply_strings(c, ptm[k], qubits, n)
        if product is not None:
            c = self._bloch_product(product, ref)
        assert c is not None
        return c.expand(-1, batch) if c.shape[1] != batch else c

    def _bloch_product(self, product: dict[int, torch.Tensor], ref: torch.Tensor) -> torch.Tensor:
        zero = _zero_bloch(ref.dtype, ref.device)[:, 0][None]
        vs = _common([product.get(q, zero) for q in range(self.num_qubits - 1, -1, -1)])
        return pauli.product(vs)


# ---- plans ------------------------------------------------------------------------------


def _batched(t: torch.Tensor | None) -> bool:
    return t is not None and t.ndim == 2


def _shared(t: torch.Tensor | None) -> torch.Tensor | None:
    """A 1-D (shared) parameter tensor as is; a batched one is never read for shared gates."""
    return None if t is None or t.ndim == 2 else t


def _concat(
    template: CircuitTemplate,
    inputs: torch.Tensor | None,
    weights: torch.Tensor | None,
    rows: int,
    ref: torch.Tensor,
) -> torch.Tensor:
    """``[inputs, weights]`` as ``(rows, P)``; an absent part is zeros (never read)."""
    parts = []
    for t, size in ((inputs, template.num_inputs), (weights, template.num_weights)):
        if t is None:
            parts.append(ref.new_zeros(rows, size))
        else:
            parts.append(t.expand(rows, size) if t.ndim == 1 else t)
    return parts[0] if not template.num_weights else torch.cat(parts, dim=1)


def _make_plan(program: Program, inputs_batched: bool, weights_batched: bool) -> _Plan:
    t = program.template
    groups: dict[tuple[str, bool], list[int]] = {}
    per_sample_of: dict[int, bool] = {}
    for gi, g in enumerate(t.gates):
        if len(g.qubits) != 1:
            continue
        per = any((inputs_batched if s < t.num_inputs else weights_batched) for s in g.slots)
        per_sample_of[gi] = per
        groups.setdefault((g.name, per), []).append(gi)
    group_list = tuple(
        _Group(name, per, tuple(gs), tuple(s for gi in gs for s in t.gates[gi].slots))
        for (name, per), gs in groups.items()
    )
    where = {gi: (k, j) for k, grp in enumerate(group_list) for j, gi in enumerate(grp.gates)}
    blocks = {}
    for i, step in enumerate(program.steps):
        if not isinstance(step, Block):
            continue
        order: list[int] = []  # block qubits in gathered order (round 0 sets it)
        rounds = []
        for r, rnd in enumerate(step.rounds):
            by_group: dict[int, list[tuple[int, int]]] = {}
            for pos, gi in zip(rnd.positions, rnd.gates, strict=True):
                k, j = where[gi]
                by_group.setdefault(k, []).append((j, step.qubits[pos]))
            parts, qubits_in_order, gates_in_order = [], [], []
            for k, items in by_group.items():
                parts.append((k, tuple(j for j, _ in items)))
                qubits_in_order += [q for _, q in items]
                gates_in_order += [group_list[k].gates[j] for j, _ in items]
            if r == 0:
                order = qubits_in_order
            positions = tuple(order.index(q) for q in qubits_in_order)
            rounds.append(_RoundPlan(tuple(parts), positions, tuple(gates_in_order)))
        per = any(per_sample_of[gi] for rnd in step.rounds for gi in rnd.gates)
        blocks[i] = _BlockPlan(tuple(order), tuple(rounds), per)
    return _Plan(group_list, blocks)


# ---- tensor kernels ---------------------------------------------------------------------


def _common(tensors: list[torch.Tensor]) -> list[torch.Tensor]:
    """Promote to one dtype (complex if any is) and one leading batch size."""
    cplx = [t for t in tensors if t.is_complex()]
    if cplx:
        tensors = [t if t.is_complex() else t.to(cplx[0].dtype) for t in tensors]
    rows = max(t.shape[0] for t in tensors)
    return [t.expand(rows, *t.shape[1:]) if t.shape[0] != rows else t for t in tensors]


def _matmul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    if a.is_complex() != b.is_complex():
        a, b = (a, b.to(a.dtype)) if a.is_complex() else (a.to(b.dtype), b)
    return a @ b


def _mv(m: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """``m @ v`` for batched matrices ``(B', k, k)`` and vectors ``(B', k)``."""
    return _matmul(m, v[..., None])[..., 0]


def _product_update(
    product: dict[int, torch.Tensor],
    qubits: tuple[int, ...],
    fused: torch.Tensor,
    size: int,
    ref: torch.Tensor,
    start: torch.Tensor | None = None,
) -> None:
    """Apply a block to unentangled per-qubit vectors (states, or vec(rho) for ``size`` 4).

    The first block acts on ``|0>``, so ``fused`` holds only the first column of each
    per-qubit product ``(B', m, size, 1)``; later ones hold the full ``(B', m, size, size)``.
    """
    if not product:
        product.update(zip(qubits, fused[..., 0].unbind(1), strict=True))
        return
    zero = _basis0(size, ref.dtype, ref.device) if start is None else start[:, 0][None]
    for q, m in zip(qubits, fused.unbind(1), strict=True):
        product[q] = _mv(m, product.get(q, zero))


@cached_constant(16)
def _zero_bloch(dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """The Bloch column ``(4, 1)`` of ``|0><0|``."""
    return torch.tensor(pauli.ZERO_STATE, dtype=dtype, device=device)[:, None]


@cached_constant(64)
def _basis0(size: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """``(1, size)`` with a one in the first place: ``|0>``, or ``vec(|0><0|)``."""
    out = torch.zeros(1, size, dtype=dtype, device=device)
    out[0, 0] = 1.0
    return out


def _apply_round(
    acc: torch.Tensor, round_ops: torch.Tensor, positions: tuple[int, ...], index: Any
) -> torch.Tensor:
    """``acc[:, p] = round_ops[:, j] @ acc[:, p]`` for ``p = positions[j]``."""
    if positions == tuple(range(acc.shape[1])):
        return _matmul(round_ops, acc)
    acc, round_ops = _common([acc, round_ops])
    pos = index(("pos", positions), positions, acc.device)
    return acc.index_copy(1, pos, round_ops @ acc.index_select(1, pos))


def _product_state(
    qubit_states: dict[int, torch.Tensor], n: int, ref: torch.Tensor
) -> torch.Tensor:
    """``v_{n-1} (x) ... (x) v_0`` (qubit 0 = LSB); qubits without gates are ``|0>``."""
    zero = _basis0(2, ref.dtype, ref.device)
    vs = _common([qubit_states.get(q, zero) for q in range(n)])
    out = vs[n - 1]
    for q in range(n - 2, -1, -1):
        out = (out[:, :, None] * vs[q][:, None, :]).reshape(out.shape[0], -1)
    return out


def _kron_unitary(per_qubit: torch.Tensor, qubits: tuple[int, ...], n: int) -> torch.Tensor:
    """``(2**n, 2**n)`` from one ``2 x 2`` per block qubit (identity elsewhere)."""
    mats = dict(zip(qubits, per_qubit.unbind(0), strict=True))
    eye = torch.eye(2, dtype=per_qubit.dtype, device=per_qubit.device)
    out = mats.get(n - 1, eye)
    for q in range(n - 2, -1, -1):
        out = torch.kron(out, mats.get(q, eye))
    return out


def _apply_unitary(psi: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
    """``psi @ u.T`` (each row of ``psi`` is a state)."""
    return _matmul(psi, u.T)


def _apply_1q(psi: torch.Tensor, m: torch.Tensor, q: int, n: int) -> torch.Tensor:
    """Apply ``(B', 2, 2)`` matrices to qubit ``q`` of states ``(B', 2**n)``."""
    rows = max(psi.shape[0], m.shape[0])
    view = psi.reshape(psi.shape[0], 2 ** (n - 1 - q), 2, 2**q)
    out = _matmul(m[:, None], view)
    return out.reshape(rows, 2**n)
