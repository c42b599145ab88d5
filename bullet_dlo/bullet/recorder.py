"""What a Bullet cable records: a row every ``record_every`` steps (:class:`CableRecord`).

The step's kernel writes a recorded step's row itself, into :class:`RecordRows` (a block of preallocated rows
that the record and the kernel share): no copies and no list appends per row. When the block is full
the record moves it into its list of blocks. Rows written from Python (the first row, a stop found outside the
kernel) go into the same block, so the rows keep their order.
"""
from __future__ import annotations

import numpy as np

from bullet_dlo.bullet.kernels import RecordRows, make_record_rows


class CableRecord:
    """Rows recorded every ``record_every`` steps: t [s], x [m], v [m/s], end forces [N], energy [J].

    ``t``, ``x``, ``v``, ``end_forces`` and ``energy`` are lists of the rows (floats, (n, 3) and (2, 3) arrays);
    :meth:`arrays` gives each as one array. ``rows``: the block the step's kernel writes into (None: one of the
    record's own, made at the first row)."""

    def __init__(self, rows: RecordRows | None = None) -> None:
        self.rows = rows
        self._blocks: list[dict[str, np.ndarray]] = []

    def append(self, t: float, x: np.ndarray, v: np.ndarray, end_forces: np.ndarray, energy: float) -> None:
        """Add a row (copies of x [m], v [m/s], (n, 3), and the end forces [N], (2, 3); t [s], energy [J])."""
        if self.rows is None:
            self.rows = make_record_rows(x.shape[0])
        b = self.rows
        k = int(b.count[0])
        b.t[k], b.x[k], b.v[k], b.end_force[k], b.energy[k] = t, x, v, end_forces, energy
        b.count[0] = k + 1
        self.written()

    def written(self) -> None:
        """After the kernel wrote a row into :attr:`rows`: a full block moves into the list (the kernel always
        finds room)."""
        b = self.rows
        if b is not None and b.count[0] >= b.t.shape[0]:
            self._blocks.append(self._take(b.t.shape[0]))
            b.count[0] = 0

    def take_from(self, rows: RecordRows) -> None:
        """Add the last row the kernel wrote into another record's block ``rows`` (this record replaced the one
        the cable made), leaving that block empty."""
        k = int(rows.count[0]) - 1
        if k >= 0:
            self.append(float(rows.t[k]), rows.x[k], rows.v[k], rows.end_force[k], float(rows.energy[k]))
            rows.count[0] = 0

    def _take(self, k: int) -> dict[str, np.ndarray]:
        b = self.rows
        return {"t": b.t[:k].copy(), "x": b.x[:k].copy(), "v": b.v[:k].copy(), "end_forces": b.end_force[:k].copy(),
                "energy": b.energy[:k].copy()}

    def arrays(self) -> dict[str, np.ndarray]:
        """Every row so far, each quantity as one array: t (k,), x, v (k, n, 3), end_forces (k, 2, 3), energy (k,)."""
        parts = list(self._blocks)
        if self.rows is not None and self.rows.count[0] > 0:
            parts.append(self._take(int(self.rows.count[0])))
        if not parts:
            return {k: np.array([]) for k in ("t", "x", "v", "end_forces", "energy")}
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}

    def __len__(self) -> int:
        live = int(self.rows.count[0]) if self.rows is not None else 0
        return sum(p["t"].shape[0] for p in self._blocks) + live

    @property
    def t(self) -> list[float]:
        return [float(a) for a in self.arrays()["t"]]

    @property
    def x(self) -> list[np.ndarray]:
        return list(self.arrays()["x"])

    @property
    def v(self) -> list[np.ndarray]:
        return list(self.arrays()["v"])

    @property
    def end_forces(self) -> list[np.ndarray]:
        return list(self.arrays()["end_forces"])

    @property
    def energy(self) -> list[float]:
        return [float(a) for a in self.arrays()["energy"]]
