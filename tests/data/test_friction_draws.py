"""The drawn cable gets the drawn friction pair (static_friction only where the capture spec samples it)."""
from __future__ import annotations

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.data.plan import cable_spec


def test_the_drawn_cable_takes_the_drawn_static_friction():
    u = {"dist": "uniform"}
    spec = CaptureSpec.from_dict({"seed": 1, "sample": {"dynamic_friction": {**u, "low": 0.3, "high": 0.5},
                                                        "static_friction": {**u, "low": 0.5, "high": 0.8}}})
    drawn = set()
    for i in range(5):
        params = spec.draw(i)
        cable = cable_spec(params)
        assert cable.static_friction == params["static_friction"] and cable.dynamic_friction == params["dynamic_friction"]
        drawn.add(cable.static_friction)
    assert len(drawn) == 5  # drawn, not the default
    assert cable_spec(CaptureSpec.from_dict({"seed": 1}).draw(0)).static_friction == 0.3  # the cable's default
