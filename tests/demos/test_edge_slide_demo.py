"""demos/edge_slide.py's yardstick: the travel of a lumped cable over a table edge as an inextensible rope (the
model's slides are measured against it in docs/concepts/contact.md, "Edges")."""
from __future__ import annotations

import math

import pytest
from demo_module import load


def _demo():
    return load("edge_slide")


def test_the_rope_holds_below_the_capstan_threshold_and_reaches_its_terminal_speed_above():
    """Below phi* = mu e / (1 + mu e) static friction holds the rope (no travel); above it, with the first node far
    from the edge (phi constant over the watch), the rope reaches the drag's terminal speed
    v = g (phi - mu e (1 - phi)) / c, so after a settle of many time constants 1/c it travels v per second."""
    rope = _demo().rope_travel
    mu, g, c = 0.3, 9.81, 5.0
    e = math.exp(mu * math.pi / 2)
    star = mu * e / (1 + mu * e)
    assert rope(40, 0.5, 0.95 * star, mu) == 0.0
    phi = 1.05 * star
    v = g * (phi - mu * e * (1 - phi)) / c
    # 2 m long, 3 segments: the next node is 0.5 x 1 m from the edge, beyond the 3 s of settle and watch
    travel = rope(3, 0.5, phi, mu, settle=2.0, seconds=1.0, drag=c, length=2.0)
    assert travel == pytest.approx(v * 1.0, rel=2e-3)
    # once a node passes the edge phi grows, and the rope goes further than at constant phi
    assert rope(40, 0.05, phi, mu, settle=0.5, seconds=1.0, drag=c) > 1.5 * v
