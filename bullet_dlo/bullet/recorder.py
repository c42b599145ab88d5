"""What a Bullet cable records: a row every ``record_every`` steps (:class:`CableRecord`)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class CableRecord:
    """Rows recorded every ``record_every`` steps: t [s], x [m], v [m/s], end forces [N], energy [J]."""

    t: list = field(default_factory=list)
    x: list = field(default_factory=list)
    v: list = field(default_factory=list)
    end_forces: list = field(default_factory=list)
    energy: list = field(default_factory=list)

    def append(self, t: float, x: np.ndarray, v: np.ndarray, end_forces: np.ndarray, energy: float) -> None:
        """Add a row (copies of x [m], v [m/s], (n, 3), and the end forces [N], (2, 3); t [s], energy [J])."""
        self.t.append(t)
        self.x.append(x.copy())
        self.v.append(v.copy())
        self.end_forces.append(end_forces.copy())
        self.energy.append(float(energy))

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.array(getattr(self, k)) for k in ("t", "x", "v", "end_forces", "energy")}
