"""Run a compiled template on torch tensors: statevector or density matrix.

The only Python loops are over the steps of the circuit (and, inside a step, over
its rounds or qubits); every sample of the batch goes through each torch operation
together. Parameters that are 1-D (shared by the batch, e.g. trained weights) keep
the gates built from them batch-free: their matrices are built once and, in the
statevector simulation, a run of such gates on a full register is multiplied into
one ``2**n x 2**n`` unitary before it touches the states.
"""

from __future__ import annotations

import string
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from qdcnn._optional import require
from qdcnn.errors import ParameterError
from qdcnn.quantum import gates as np_gates
from qdcnn.quantum.circuits import CircuitTemplate
from qdcnn.quantum.torchsim.gates import complex_dtype, gate_matrices
from qdcnn.quantum.torchsim.measure import (
    density_probabilities,
    readout_matrix,
    sampled,
    state_probabilities,
    z_expectations,
)
from qdcnn.quantum.torchsim.program import Block, Channels, Monomial, Program, compile_template

require("torch", "the PyTorch quantum simulator")
import torch  # noqa: E402

#: Largest register whose batch-free gate runs are multiplied into one unitary.
FUSE_UNITARY_MAX_QUBITS = 6


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
        if t.ndim not in (1, 2) or t.shape[-1] != size:
            raise ParameterError(label, f"shape {tuple(t.shape)}", f"({size},) or (B, {size})")
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

    def __init__(self, template: CircuitTemplate, noise: Any = None) -> None:
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
        return self._evolve_density(inputs, weights)

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
            probs = density_probabilities(self._evolve_density(inputs, weights))
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
            if group.per_sample:
                if full is None:
                    full = _concat(t, inputs, weights, batch, ref)
                source = full
            else:
                if shared is None:
                    shared = _concat(t, _shared(inputs), _shared(weights), 1, ref)
                source = shared
            idx = self._index(("slots", group.slots), group.slots, ref.device)
            count = np_gates.ANGLE_COUNT[group.name]
            angles = source.index_select(1, idx).view(source.shape[0], len(group.gates), count)
            out.append(gate_matrices(group.name, angles, ref))
        return out

    def _index(self, key: Any, values: Any, device: torch.device) -> torch.Tensor:
        full_key = (key, device)
        if full_key not in self._consts:
            self._consts[full_key] = torch.as_tensor(np.asarray(values), device=device)
        out: torch.Tensor = self._consts[full_key]
        return out

    def _const(self, key: Any, make: Any, ref: torch.Tensor) -> Any:
        full_key = (key, ref.dtype, ref.device)
        if full_key not in self._consts:
            self._consts[full_key] = make()
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
                if not bp.per_sample and n <= FUSE_UNITARY_MAX_QUBITS:
                    u = _kron_unitary(fused[0], bp.qubits, n)
                    pending = u if pending is None else _matmul(u, pending)
                    continue
                if pending is not None:
                    psi, pending = _apply_unitary(psi, pending), None
                for j, q in enumerate(bp.qubits):
                    psi = _apply_1q(psi, fused[:, j], q, n)
            elif isinstance(step, Monomial):
                if product is not None:
                    psi, product = _product_state(product, n, batch, ref), None
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
            psi = _product_state(product, n, batch, ref)
        assert psi is not None
        if pending is not None:
            psi = _apply_unitary(psi, pending)
        return psi.expand(batch, -1) if psi.shape[0] != batch else psi

    # ---- density matrix ------------------------------------------------------------

    def _superops(self, ref: torch.Tensor) -> list[torch.Tensor]:
        """Each distinct Kraus set as a superoperator ``(4**m, 4**m)``."""

        def make() -> list[torch.Tensor]:
            out = []
            cdt = complex_dtype(ref.dtype)
            for k in self.program.kraus:
                kt = torch.as_tensor(k, dtype=cdt, device=ref.device)
                d = k.shape[-1]
                out.append(torch.einsum("aik,ajl->ijkl", kt, kt.conj()).reshape(d * d, d * d))
            return out

        out: list[torch.Tensor] = self._const("superops", make, ref)
        return out

    def _round_noise(self, rp: _RoundPlan, ref: torch.Tensor) -> torch.Tensor | None:
        """``(k, 4, 4)`` noise superoperators after the round's gates (``None``: no noise)."""
        fused = self.program.fused_noise
        if not any(g in fused for g in rp.gates):
            return None

        def make() -> torch.Tensor:
            sup = self._superops(ref)
            eye = torch.eye(4, dtype=complex_dtype(ref.dtype), device=ref.device)
            mats = []
            for g in rp.gates:
                m = eye
                for k in fused.get(g, ()):
                    m = sup[k] @ m
                mats.append(m)
            return torch.stack(mats)

        return self._const(("round-noise", rp.gates), make, ref)

    def _fuse_super(
        self, bp: _BlockPlan, mats: list[torch.Tensor], ref: torch.Tensor, columns: bool
    ) -> torch.Tensor:
        """Per-qubit superoperators ``(B', m, 4, 4)`` of gate-then-noise, or first columns."""

        def round_super(rp: _RoundPlan) -> torch.Tensor:
            u = self._round(rp, mats)
            u = u if u.is_complex() else u.to(complex_dtype(u.dtype))
            s = _super(u)
            noise = self._round_noise(rp, ref)
            return s if noise is None else noise @ s

        first = round_super(bp.rounds[0])
        acc = first[..., :1] if columns else first
        for rp in bp.rounds[1:]:
            acc = _apply_round(acc, round_super(rp), rp.positions, self._index)
        return acc

    def _evolve_density(
        self, inputs: torch.Tensor | None, weights: torch.Tensor | None
    ) -> torch.Tensor:
        inputs, weights, batch, ref = _check_params(self.template, inputs, weights)
        plan = self._plan(_batched(inputs), _batched(weights))
        mats = self._matrices(plan, inputs, weights, batch, ref)
        n = self.num_qubits
        cdt = complex_dtype(ref.dtype)
        product: dict[int, torch.Tensor] | None = {}  # qubit -> vec(rho_q) (B', 4)
        rho: torch.Tensor | None = None
        for i, step in enumerate(self.program.steps):
            if isinstance(step, Block):
                bp = plan.blocks[i]
                if product is not None:
                    fused = self._fuse_super(bp, mats, ref, columns=not product)
                    _product_update(product, bp.qubits, fused, 4, ref)
                    continue
                assert rho is not None
                fused = self._fuse_super(bp, mats, ref, columns=False)
                for j, q in enumerate(bp.qubits):
                    rho = _apply_superop(rho, fused[:, j], (q,), n)
                continue
            if product is not None:
                rho, product = _product_density(product, n, cdt, ref.device), None
            assert rho is not None
            if isinstance(step, Monomial):
                d = 2**n
                idx = self._index(
                    ("perm2", i), (step.perm[:, None] * d + step.perm[None, :]).ravel(), ref.device
                )
                rho = rho.reshape(rho.shape[0], d * d).index_select(1, idx).view(-1, d, d)
                if step.sign is not None:
                    outer = np.outer(step.sign, step.sign)
                    rho = rho * self._const(
                        ("sign2", i),
                        lambda o=outer: torch.as_tensor(o, dtype=ref.dtype, device=ref.device),
                        ref,
                    )
            elif isinstance(step, Channels):
                sup = self._superops(ref)
                for qubits, k in step.channels:
                    rho = _apply_superop(rho, sup[k][None], qubits, n)
        if product is not None:
            rho = _product_density(product, n, cdt, ref.device)
        assert rho is not None
        return rho.expand(batch, -1, -1) if rho.shape[0] != batch else rho


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
) -> None:
    """Apply a block to unentangled per-qubit vectors (states, or vec(rho) for ``size`` 4).

    The first block acts on ``|0>``, so ``fused`` holds only the first column of each
    per-qubit product ``(B', m, size, 1)``; later ones hold the full ``(B', m, size, size)``.
    """
    if not product:
        product.update({q: fused[:, j, :, 0] for j, q in enumerate(qubits)})
        return
    zero = ref.new_zeros(1, size)
    zero[0, 0] = 1.0
    for j, q in enumerate(qubits):
        product[q] = _mv(fused[:, j], product.get(q, zero))


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
    qubit_states: dict[int, torch.Tensor], n: int, batch: int, ref: torch.Tensor
) -> torch.Tensor:
    """``v_{n-1} (x) ... (x) v_0`` (qubit 0 = LSB); qubits without gates are ``|0>``."""
    zero = ref.new_zeros(1, 2)
    zero[0, 0] = 1.0
    vs = _common([qubit_states.get(q, zero) for q in range(n)])
    out = vs[n - 1]
    for q in range(n - 2, -1, -1):
        out = (out[:, :, None] * vs[q][:, None, :]).reshape(out.shape[0], -1)
    return out


def _product_density(
    qubit_vecs: dict[int, torch.Tensor], n: int, cdt: torch.dtype, device: torch.device
) -> torch.Tensor:
    """``rho_{n-1} (x) ... (x) rho_0`` from per-qubit ``vec(rho_q)`` (row-major 2 x 2)."""
    zero = torch.zeros(1, 4, dtype=cdt, device=device)
    zero[0, 0] = 1.0
    rs = _common([qubit_vecs.get(q, zero) for q in range(n)])
    out = rs[n - 1].reshape(-1, 2, 2)
    for q in range(n - 2, -1, -1):
        r = rs[q].reshape(-1, 2, 2)
        a = out.shape[-1]
        out = (out[:, :, None, :, None] * r[:, None, :, None, :]).reshape(-1, 2 * a, 2 * a)
    return out


def _kron_unitary(per_qubit: torch.Tensor, qubits: tuple[int, ...], n: int) -> torch.Tensor:
    """``(2**n, 2**n)`` from one ``2 x 2`` per block qubit (identity elsewhere)."""
    mats = {q: per_qubit[j] for j, q in enumerate(qubits)}
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


def _super(u: torch.Tensor) -> torch.Tensor:
    """``U (x) conj(U)``: the superoperator of ``rho -> U rho U^dagger``, shape ``(..., 4, 4)``."""
    s = u[..., :, None, :, None] * u.conj()[..., None, :, None, :]
    return s.reshape(*u.shape[:-2], 4, 4)


@lru_cache(maxsize=256)
def _superop_subscripts(n: int, qubits: tuple[int, ...]) -> str:
    """einsum spec applying an ``m``-qubit superoperator to ``rho`` viewed as ``2n`` axes.

    The superoperator is viewed as ``(B', [2]*m ket-out, [2]*m bra-out, [2]*m ket-in,
    [2]*m bra-in)``, each group most significant bit first (``qubits[-1]`` first).
    """
    letters = iter(string.ascii_letters)
    batch = next(letters)
    ket = {q: next(letters) for q in range(n)}
    bra = {q: next(letters) for q in range(n)}
    ket_out = {q: next(letters) for q in qubits}
    bra_out = {q: next(letters) for q in qubits}
    msb_first = tuple(reversed(qubits))
    sup = (
        "".join(ket_out[q] for q in msb_first)
        + "".join(bra_out[q] for q in msb_first)
        + "".join(ket[q] for q in msb_first)
        + "".join(bra[q] for q in msb_first)
    )
    order = range(n - 1, -1, -1)
    rho_in = "".join(ket[q] for q in order) + "".join(bra[q] for q in order)
    rho_out = "".join(ket_out.get(q, ket[q]) for q in order) + "".join(
        bra_out.get(q, bra[q]) for q in order
    )
    return f"{batch}{sup},{batch}{rho_in}->{batch}{rho_out}"


def _apply_superop(
    rho: torch.Tensor, sup: torch.Tensor, qubits: tuple[int, ...], n: int
) -> torch.Tensor:
    """Apply superoperators ``(B', 4**m, 4**m)`` on ``qubits`` to ``rho`` ``(B', d, d)``."""
    m = len(qubits)
    d = 2**n
    spec = _superop_subscripts(n, qubits)
    s = sup.reshape(sup.shape[0], *([2] * (4 * m)))
    r = rho.reshape(rho.shape[0], *([2] * (2 * n)))
    if r.is_complex() != s.is_complex():
        r = r.to(s.dtype)
    out = torch.einsum(spec, s, r)
    return out.reshape(out.shape[0], d, d)
