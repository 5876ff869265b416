"""Shared fixtures: small scenes under tests/data and the repository's paper scenes."""

from __future__ import annotations

from pathlib import Path

import pytest

import diffsoft

DATA = Path(__file__).parent / "data"
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def beam() -> diffsoft.Scene:
    """A 24-tet beam held at one end by penalty attachments, thrown upwards (no contact)."""
    s = diffsoft.Scene.load(DATA / "beam.json")
    # A fixed number of iterations: the forward is a smooth function of the parameters, so
    # central differences converge to the reverse-mode gradient.
    s.configure(tolerance=0.0, max_iterations=15)
    return s


@pytest.fixture
def ground() -> diffsoft.Scene:
    """A box thrown onto frictional ground."""
    s = diffsoft.Scene.load(DATA / "ground.json")
    s.configure(tolerance=0.0, max_iterations=15)
    return s


@pytest.fixture
def bridgesus() -> diffsoft.Scene:
    """The paper's bridgesus scene (its own file format)."""
    return diffsoft.Scene.load(REPO / "verification/paper/bridgesus/bridgesus.json")


def central(f, x: float, h: float) -> float:
    """Central difference of a scalar function."""
    return (f(x + h) - f(x - h)) / (2 * h)
