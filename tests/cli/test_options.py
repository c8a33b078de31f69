"""One interface: every command's options walked, one name, type, default and help per concept.

The tables below name the exceptions, each with its reason; a new option that breaks a
rule fails here until it follows the rule or joins a table with a reason.
"""

from __future__ import annotations

import types
import typing
from collections import defaultdict
from collections.abc import Iterator
from typing import Any

import pytest
import typer.main
from typer.testing import CliRunner

from qdcnn.cli import app

runner = CliRunner()

#: The lane options, defined once in cli/_common.py (LaneOptions turns them into the config).
LANE_OPTIONS = (
    "--lanes",
    "--features",
    "--edges",
    "--shadow-removal",
    "--marks",
    "--segment-angles",
    "--inner-lines",
    "--track",
)
#: The commands that run the lane stage with a pipeline the user chooses.
LANE_COMMANDS = ("evaluate", "train-direction", "noise-sweep", "run", "detect-lanes")
#: Commands that run the lane stage with pipelines of their own, and why they take no lane options.
FIXED_PIPELINES = {
    "reproduce": "reports the paper's pipeline and the named options side by side",
    "demo": "reproduce --quick on the synthetic presets",
    "bench pipeline": "times one fixed lane-stage config, comparable across runs",
}
#: Old spellings kept as hidden aliases (they print a deprecation note): command, old, new.
ALIASES = (
    ("noise-sweep", "--methods", "--method"),
    ("train-shadows", "--data", "--shadow-set"),
)
#: Spellings of one concept of which only the first may be visible.
SYNONYMS = (("--method", "--methods"), ("--shadow-set", "--shadow-sets"))
#: Names a plural apart that are different things.
NOT_PLURALS = {
    ("--centroid", "--centroids"): "a centroid value (detect-shadows) vs a number of them",
    ("--seed", "--seeds"): "one seed vs how many seeds evaluate retrains with",
}
#: Options whose help names what they are in that command (what is written, seeded, read).
HELP_PER_COMMAND = {
    "--out": "what is written differs per command",
    "--data": "what the data is used for differs",
    "--method": "the method families differ (shadow, lane, quantum)",
    "--model": "the model kind differs (shadow, direction, hybrid head)",
    "--seed": "what the seed drives differs",
    "--force": "what is redone or replaced differs",
    "--frames": "what is timed differs",
    "--shots": "where shots are taken differs",
    "--scheduler": "what is distributed differs: folds or chunks",
    "--weights": "circuit: gate angles; evaluate/train-direction: ImageNet weights",
    "--features": "train-shadows: the shadow model's features, not the lane features",
    "--quick": "demo's default is the quick profile, reproduce's the full one",
    "--cnn": "reproduce trains the CNNs, bench pipeline times them",
    "--shadow-set": "how the shadow set is used differs",
    "--video": "synth writes the drive, run the overlay",
    "--label-threshold": "score defaults to the saved model's own label settings",
    "--steering-unit": "score defaults to the saved model's own label settings",
}
#: Options whose default differs per command, and why.
DEFAULT_PER_COMMAND = {
    "--method": "each command's own default method",
    "--out": "reproduce and demo have default folders, the others none",
    "--data": "bench pipeline has a default drive, the others none",
    "--frames": "each benchmark's own size",
    "--shots": "detect-shadows samples (paper: 1024), noise-sweep and circuit are exact",
    "--quick": "demo is reproduce --quick",
    "--cnn": "reproduce chooses from torch and the profile",
    "--video": "synth writes no video unless asked, run writes the overlay",
    "--label-threshold": "score: the saved model's own label settings unless given",
    "--steering-unit": "score: the saved model's own label settings unless given",
    "--features": "train-shadows: the shadow model's features",
}
#: Options whose type or form differs per command, and why.
TYPE_PER_COMMAND = {
    "--data": "reproduce takes LABEL=SPEC, repeated",
    "--weights": "circuit: gate angles as text; the others: a weights file",
}


def _commands() -> Iterator[tuple[str, Any]]:
    """Every leaf command with its full name (``bench pipeline``)."""

    def walk(command: Any, prefix: str) -> Iterator[tuple[str, Any]]:
        subcommands = getattr(command, "commands", None)
        if subcommands is None:
            yield prefix, command
            return
        for name, sub in subcommands.items():
            yield from walk(sub, f"{prefix} {name}".strip())

    yield from walk(typer.main.get_command(app), "")


COMMANDS = dict(_commands())


def _options(command: Any, hidden: bool = False) -> dict[str, Any]:
    """The command's options by their first name (visible ones unless ``hidden``)."""
    return {
        p.opts[0]: p
        for p in command.params
        if p.param_type_name == "option" and getattr(p, "hidden", False) == hidden
    }


def _shared() -> dict[str, list[tuple[str, Any]]]:
    """Each visible option name with the commands that have it."""
    by_name: dict[str, list[tuple[str, Any]]] = defaultdict(list)
    for name, command in COMMANDS.items():
        for opt, param in _options(command).items():
            by_name[opt].append((name, param))
    return {opt: uses for opt, uses in by_name.items() if len(uses) > 1}


def _form(param: Any) -> tuple[Any, ...]:
    """The value type (``None`` left out: ``int | None`` is ``int``) and the flag form."""
    descriptor = getattr(param, "type_descriptor", None)  # Typer 0.24+: no click type
    kind = descriptor.annotation if descriptor is not None else param.type.name
    args = [a for a in typing.get_args(kind) if a is not type(None)]
    if len(args) == 1 and typing.get_origin(kind) in (typing.Union, types.UnionType):
        kind = args[0]
    return (str(kind), param.multiple, param.is_flag, tuple(param.secondary_opts))


def test_every_command_is_walked_and_every_exception_is_a_shared_option() -> None:
    assert {"bench shadows", "bench pipeline", "noise-sweep", "run", "reproduce"} <= set(COMMANDS)
    exceptions = {*HELP_PER_COMMAND, *DEFAULT_PER_COMMAND, *TYPE_PER_COMMAND}
    assert exceptions <= set(_shared())


@pytest.mark.parametrize("opt", sorted(_shared()))
def test_an_option_shared_by_name_has_one_form_default_and_help(opt: str) -> None:
    uses = _shared()[opt]
    if opt not in TYPE_PER_COMMAND:
        assert len({_form(p) for _, p in uses}) == 1, [(c, _form(p)) for c, p in uses]
    if opt not in DEFAULT_PER_COMMAND:
        assert len({repr(p.default) for _, p in uses}) == 1, [(c, p.default) for c, p in uses]
    if opt not in HELP_PER_COMMAND:
        assert len({p.help for _, p in uses}) == 1, [(c, p.help) for c, p in uses]


def test_no_concept_is_visible_under_two_names() -> None:
    visible = {opt for command in COMMANDS.values() for opt in _options(command)}
    for name, *others in SYNONYMS:
        assert not set(others) & visible, f"use {name}"
    plurals = {(o, o + "s") for o in visible if o + "s" in visible}
    assert plurals <= set(NOT_PLURALS), plurals - set(NOT_PLURALS)


@pytest.mark.parametrize(("command", "old", "new"), ALIASES)
def test_old_spellings_are_hidden_aliases(command: str, old: str, new: str) -> None:
    assert new in _options(COMMANDS[command])
    assert old not in _options(COMMANDS[command])
    assert old in _options(COMMANDS[command], hidden=True)


@pytest.mark.parametrize("command", LANE_COMMANDS)
def test_every_lane_stage_command_takes_every_lane_option(command: str) -> None:
    options = _options(COMMANDS[command])
    assert set(LANE_OPTIONS) <= set(options)
    reference = _options(COMMANDS["evaluate"])
    for opt in LANE_OPTIONS:
        mine, theirs = options[opt], reference[opt]
        assert (_form(mine), mine.default, mine.help) == (
            _form(theirs),
            theirs.default,
            theirs.help,
        ), opt


def test_commands_without_lane_options_say_why() -> None:
    for name, command in COMMANDS.items():
        lane = set(LANE_OPTIONS) & set(_options(command))
        if name == "train-shadows":  # its --features are the shadow model's
            lane -= {"--features"}
        assert not lane or name in LANE_COMMANDS, name
    assert set(FIXED_PIPELINES) <= set(COMMANDS)


def test_force_is_a_force_no_force_pair_everywhere() -> None:
    forced = {n: _options(c)["--force"] for n, c in COMMANDS.items() if "--force" in _options(c)}
    assert {"run", "detect-lanes", "detect-shadows", "reproduce", "demo"} <= set(forced)
    for name, param in forced.items():
        assert param.secondary_opts == ["--no-force"] and param.default is False, name


def test_methods_still_works_on_noise_sweep_with_a_deprecation_note() -> None:
    res = runner.invoke(app, ["noise-sweep", "--methods", "uu,dnn", "--json"])
    assert res.exit_code == 2 and res.stdout == ""
    lines = res.stderr.splitlines()
    assert lines[0] == "note: --methods is deprecated; use --method"
    assert "methods='dnn' is invalid" in " ".join(lines[1:])  # the value was used


def test_data_still_works_on_train_shadows_with_a_deprecation_note(tmp_path: Any) -> None:
    args = ["train-shadows", "--data", str(tmp_path / "none"), "--out", str(tmp_path / "m.json")]
    res = runner.invoke(app, args)
    assert res.exit_code == 2
    assert res.stderr.startswith("note: --data is deprecated; use --shadow-set\n")
    assert "none" in res.stderr.splitlines()[1]  # the value was used
    res = runner.invoke(app, ["train-shadows", "--out", str(tmp_path / "m.json")])
    assert res.exit_code == 2 and "Missing option '--shadow-set'" in res.stderr


def test_noise_sweep_reads_the_lane_options() -> None:
    res = runner.invoke(app, ["noise-sweep", "--data", "synthetic:track1:30", "--edges", "hsv"])
    assert res.exit_code == 2 and "edges='hsv' is invalid" in res.stderr


@pytest.mark.parametrize("command", ["run", "detect-lanes"])
def test_a_model_file_and_lane_options_are_one_error(command: str, tmp_path: Any) -> None:
    import numpy as np

    from qdcnn.data.images import write_image

    model = tmp_path / "m.qdcnn"
    model.write_bytes(b"")
    images = tmp_path / "img"
    images.mkdir()
    write_image(images / "f.png", np.zeros((16, 32, 3), np.uint8))  # inputs are checked first
    args = [command, str(images), "--out", str(tmp_path / "o"), "--model", str(model)]
    res = runner.invoke(app, [*args, "--lanes", "paper"])
    assert res.exit_code == 2
    assert "carries the lane settings it was trained with" in " ".join(res.stderr.split())


@pytest.mark.parametrize(
    ("extra", "first", "second"),
    [
        (["--model", "{model}", "--centroid", "80"], "--model", "--centroid"),
        (["--method", "ibt", "--model", "{model}"], "--model", "--method ibt"),
        (["--exact", "--shots", "5"], "--exact", "--shots"),
    ],
)
def test_conflicting_shadow_options_are_one_error_naming_both(
    extra: list[str], first: str, second: str, tmp_path: Any
) -> None:
    import numpy as np

    from qdcnn.data.images import write_image

    write_image(tmp_path / "a.png", np.zeros((16, 32, 3), np.uint8))
    model = tmp_path / "shadow.json"
    model.write_text("{}")
    args = [a.replace("{model}", str(model)) for a in extra]
    out = tmp_path / "o"
    res = runner.invoke(app, ["detect-shadows", str(tmp_path / "a.png"), "--out", str(out), *args])
    assert res.exit_code == 2, res.stderr
    assert res.stderr.startswith("error: ") and len(res.stderr.splitlines()) == 1
    assert f"{first} and {second} cannot be used together" in res.stderr
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "names"),
    [
        (["--gap", "1000"], ("--inner-folds 3", "--gap 1000", "60 training frames")),
        (["--inner-folds", "50"], ("--inner-folds 50", "--gap 5", "60 training frames")),
    ],
)
def test_train_direction_refuses_an_inner_search_that_cannot_run(
    extra: list[str], names: tuple[str, ...], tmp_path: Any
) -> None:
    out = tmp_path / "m.safetensors"
    args = ["train-direction", "--data", "synthetic:track2:60", "--out", str(out), *extra]
    res = runner.invoke(app, args)
    assert res.exit_code == 2, res.stderr
    assert res.stderr.startswith("error: ") and len(res.stderr.splitlines()) == 1
    assert all(name in res.stderr for name in names), res.stderr
    assert not out.exists()


@pytest.mark.parametrize(
    ("data", "names"),
    [
        (
            ["--data", "synthetic:track1:120", "--folds", "2"],
            ("--inner-folds 50", "--gap 5", "55 training frames", "--folds 2"),
        ),
        (
            ["--train", "synthetic:track2:120", "--test", "synthetic:track1:30"],
            ("--inner-folds 50", "--gap 5", "120 training frames (--train)"),
        ),
    ],
)
def test_evaluate_refuses_an_inner_search_that_cannot_run(
    data: list[str], names: tuple[str, ...]
) -> None:
    args = ["evaluate", *data, "--method", "image-split-uu", "--inner-folds", "50"]
    res = runner.invoke(app, args)
    assert res.exit_code == 2, res.stderr
    assert res.stderr.startswith("error: ") and len(res.stderr.splitlines()) == 1, res.stderr
    assert all(name in res.stderr for name in names), res.stderr


def test_equal_segment_angles_are_refused_in_the_user_s_words(tmp_path: Any) -> None:
    out = tmp_path / "m.safetensors"
    args = ["train-direction", "--data", "synthetic:track2:60", "--out", str(out)]
    res = runner.invoke(app, [*args, "--segment-angles", "45,45"])
    assert res.exit_code == 2 and len(res.stderr.splitlines()) == 1
    assert "segment_angles='45,45' is invalid: LO,HI degrees" in res.stderr
    assert "no row has both slopes" not in res.stderr and not out.exists()
