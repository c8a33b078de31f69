"""The test command: ``pip install nox && nox`` runs both sessions (README states the time).

- ``base``: the base install (no extras), only the tests marked ``base``: what differs
  without extras (the missing-extra errors, the base commands, the cheap imports).
- ``full``: every extra; ruff, mypy, then the whole suite.
"""

from __future__ import annotations

import nox

nox.options.sessions = ["base", "full"]
nox.options.error_on_missing_interpreters = True

# A bare ``torch`` requirement pulls a multi-GB CUDA build; this pin takes the CPU one.
TORCH = "torch==2.13.0"


@nox.session
def base(session: nox.Session) -> None:
    """The base install's job: what differs without the extras."""
    session.install("-e", ".", "pytest", "hypothesis")
    session.run("python", "-m", "pytest", "-q", "-m", "base", *session.posargs)


@nox.session
def full(session: nox.Session) -> None:
    """Every extra: lint, types, the whole suite."""
    session.install(TORCH, "-e", ".[all,dev]")
    session.run("ruff", "check", ".")
    session.run("mypy")
    # The slowest tests are listed so that a CI log shows where its time goes.
    session.run("python", "-m", "pytest", "-q", "--durations=30", *session.posargs)
