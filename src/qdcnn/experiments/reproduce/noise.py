"""Fig. 7: direction accuracy against noise strength for the six channels, and the shadow BER.

Runs :func:`qdcnn.experiments.noise.direction_sweep` on each dataset's lane features
(models trained without noise, evaluated under each channel and strength with exact
density-matrix probabilities, the protocol's contiguous folds) and
:func:`~qdcnn.experiments.noise.shadow_sweep` on the shadow set; figures by
:mod:`qdcnn.experiments.noise.plot`, with the points the paper's text states marked.
"""

from __future__ import annotations

from typing import Any

from qdcnn.errors import QdcnnError
from qdcnn.experiments.reproduce.accuracy import PROTOCOL
from qdcnn.experiments.reproduce.context import DatasetUnavailable, RunContext
from qdcnn.experiments.reproduce.model import Cell, Section, cell
from qdcnn.experiments.reproduce.paper_values import NOISE_POINTS, NOISE_TEXT
from qdcnn.experiments.reproduce.spec import DatasetEntry

__all__ = ["noise_section"]


def noise_section(ctx: RunContext, section: Section) -> None:
    """Fig. 7 on every dataset, then the shadow detector's BER against noise."""
    from qdcnn.quantum.noise import PAPER_CHANNELS

    groupings = ctx.profile.noise_groupings
    section.text(
        "Models trained once without noise, then evaluated under each channel at "
        f"p = {', '.join(f'{p:g}' for p in ctx.profile.noise_strengths)} with exact density-matrix "
        "probabilities; the channel acts after every gate on every qubit it touches (as a "
        "Qiskit Aer NoiseModel does); phase damping is the textbook channel. Accuracy pooled "
        f"over the protocol's {PROTOCOL['folds']} contiguous folds. Groupings: "
        f"{', '.join(groupings)}. Stars and crosses mark the values the paper's text gives "
        "with their strength; its other statements are quoted under each table. At p = 0 the "
        "UU† rule here uses exact probabilities, Table I its 1024-shot estimates, so the two "
        "can differ slightly."
    )
    data: dict[str, Any] = {
        "channels": list(PAPER_CHANNELS),
        "strengths": list(ctx.profile.noise_strengths),
        "direction": {},
    }
    for entry in ctx.datasets:
        try:
            data["direction"][entry.key] = _direction(ctx, section, entry, PAPER_CHANNELS)
        except DatasetUnavailable as exc:
            section.error(str(exc))
    try:
        data["shadow"] = _shadow(ctx, section, PAPER_CHANNELS)
    except QdcnnError as exc:
        section.error(f"shadow BER against noise: {exc}")
    section.data = data
    if not data["direction"] and "shadow" not in data:
        section.status = "failed"


def _direction(
    ctx: RunContext, section: Section, entry: DatasetEntry, channels: tuple[str, ...]
) -> list[dict[str, Any]]:
    from qdcnn.experiments import noise as ns
    from qdcnn.experiments.noise.plot import accuracy_figure
    from qdcnn.experiments.reproduce.plots import mark_paper_noise_points

    lanes = ctx.lane_data(entry, "paper")
    groupings = ctx.profile.noise_groupings
    total = (
        len(ns.DIRECTION_METHODS)
        * len(groupings)
        * len(channels)
        * len(ctx.profile.noise_strengths)
    )
    with ctx.reporter.progress(total, f"noise sweep, {entry.key} ({lanes.frames.name})") as step:
        rows = ns.direction_sweep(
            {g: lanes.features(g) for g in groupings},
            lanes.y,
            methods=ns.DIRECTION_METHODS,
            channels=channels,
            strengths=ctx.profile.noise_strengths,
            config=ctx.configs["paper"],
            seed=ctx.spec.seed,
            on_step=step,
            folds=PROTOCOL["folds"],
            gap=PROTOCOL["gap"],
            inner_folds=PROTOCOL["inner_folds"],
        )
    result = ns.NoiseSweepResult(
        lanes.frames.name,
        rows,
        channels,
        ctx.profile.noise_strengths,
        seed=ctx.spec.seed,
        protocol=dict(PROTOCOL),
    )
    fig = accuracy_figure(result)
    mark_paper_noise_points(fig, channels, entry.label)
    section.figure(
        ctx.save_figure(fig, f"fig-7-{entry.key}"),
        f"{entry.title} ({lanes.frames.name}): direction accuracy against noise strength p "
        "per channel; dashed: majority class.",
        alt=f"noise sweep {entry.key}",
    )
    section.table(*_direction_table(result, entry), caption=f"{entry.title}: measured vs paper")
    for kind in ns.DIRECTION_METHODS:
        text = NOISE_TEXT.get((entry.label, kind))
        if text:
            section.text(f"Paper, {entry.title}, {'UU†' if kind == 'uu' else 'VQC'}: {text}.")
    out: list[dict[str, Any]] = result.to_dicts()
    return out


def _extremes(series: list[tuple[float, float]], digits: int = 3) -> tuple[str, str, str]:
    """The value at p = 0, the lowest and the highest (with their p) of one series."""
    p0 = next((a for p, a in series if p == 0.0), None)
    lo = min(series, key=lambda t: t[1])
    hi = max(series, key=lambda t: t[1])
    return (
        "—" if p0 is None else f"{p0:.{digits}f}",
        f"{lo[1]:.{digits}f} (p={lo[0]:g})",
        f"{hi[1]:.{digits}f} (p={hi[0]:g})",
    )


def _direction_table(result: Any, entry: DatasetEntry) -> tuple[list[str], list[list[Cell]]]:
    rows: list[list[Cell]] = []
    for label in result.labels():
        kind = label.rpartition("-")[2]
        for channel in result.channels:
            p, acc = result.series(label, channel)
            at0, lo, hi = _extremes(list(zip(p.tolist(), acc.tolist(), strict=True)))
            paper = [
                f"{a:g} at p={q:g}"
                for d, k, ch, q, a in NOISE_POINTS
                if d == entry.label and k == kind and ch == channel
            ]
            rows.append(
                [
                    label,
                    channel,
                    cell(at0, "measured"),
                    cell(lo, "measured"),
                    cell(hi, "measured"),
                    cell("; ".join(paper), "paper"),
                ]
            )
    return ["series", "channel", "p = 0", "lowest", "highest", "paper (text)"], rows


def _shadow(ctx: RunContext, section: Section, channels: tuple[str, ...]) -> dict[str, Any]:
    from qdcnn.experiments import noise as ns
    from qdcnn.experiments.noise.plot import shadow_figure

    name, images, masks, _ = ctx.shadow_set()
    tr, te = ns.split_train_test(len(images))
    total = len(channels) * len(ctx.profile.noise_strengths)
    with ctx.reporter.progress(total, f"shadow noise sweep ({name})") as step:
        rows, model = ns.shadow_sweep(
            images[tr],
            masks[tr],
            images[te],
            masks[te],
            channels=channels,
            strengths=ctx.profile.noise_strengths,
            config=ctx.configs["paper"].shadow,
            seed=ctx.spec.seed,
            on_step=step,
        )
    protocol = {"shadow_train": tr.stop - tr.start, "shadow_test": te.stop - te.start}
    result = ns.NoiseSweepResult(
        None,
        rows,
        channels,
        ctx.profile.noise_strengths,
        seed=ctx.spec.seed,
        shadow_set=name,
        protocol=protocol,
    )
    section.figure(
        ctx.save_figure(shadow_figure(result), "fig-7-shadow-ber"),
        f"UU† shadow detection BER (%) against noise strength on {name}: centroid trained on "
        f"{protocol['shadow_train']} images, scored on {protocol['shadow_test']}. The paper "
        "shows no shadow BER under noise.",
        alt="shadow BER against noise",
    )
    table: list[list[Cell]] = []
    for channel in channels:
        p, ber = result.series(ns.SHADOW_METHOD, channel, "ber")
        at0, lo, hi = _extremes(list(zip(p.tolist(), ber.tolist(), strict=True)), digits=1)
        table.append([channel, cell(at0, "measured"), cell(lo, "measured"), cell(hi, "measured")])
    section.table(
        ["channel", "BER % at p = 0", "lowest", "highest"],
        table,
        caption="UU† shadow BER against noise (measured)",
    )
    return {
        "set": name,
        "protocol": protocol,
        "threshold": model.threshold,
        "rows": result.to_dicts(),
    }
