"""Two cables crossing: a Lv cable lying on the ground along x, a second one dropped across it along y.

Prints, per rate and n: whether either cable was called unstable (and why), the smallest centre-line
distance between the two cables at the end (the clearance; r1 + r2 = 4 mm at rest) and over the run,
how far the upper cable's middle sank below the lower one's top, and the ground's support of both
cables against their weight (model contact only).

    PYTHONPATH=. python demos/cable_cable.py [--drop 0.03] [--duration 1.5] [--n 10 20 40] [--shift 0.5] [--rates 60 240 1000] [--cost]
    PYTHONPATH=. python demos/cable_cable.py --heavy [--rates 60 240]
    PYTHONPATH=. python demos/cable_cable.py --along [--rates 60 240 1000] [--n 10 40]

``--heavy``: a 300 g, 10 mm cable (n 12) laid 0.1 mm above a 10 g, 2 mm one (n 40) instead: the contact forces each
cable feels from the other and the ground's support of both weights over 3 s (the staggered steps' slow settling).
``--along``: a cable laid 0.1 mm above another one along its length (same n; then n and the last n of --n below it;
then a 6 mm cable shifted 1 cm along a 4 mm one): per case, at 1 s, the vertical force each feels from the other
over the upper one's weight (equal and opposite: +1 and -1), the ground's support of both weights, the largest speed
and whether a cable was stopped.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.model import CableState
from bullet_dlo.core.spec import CableSpec


def segment_distance(xa: np.ndarray, xb: np.ndarray) -> float:
    """Smallest distance [m] between the polylines xa (n, 3) and xb (m, 3) (segment-segment closest points)."""
    best = np.inf
    for i in range(len(xa) - 1):
        p0, d1 = xa[i], xa[i + 1] - xa[i]
        for j in range(len(xb) - 1):
            q0, d2 = xb[j], xb[j + 1] - xb[j]
            r = p0 - q0
            a, e, f = d1 @ d1, d2 @ d2, d2 @ r
            c, b = d1 @ r, d1 @ d2
            den = a * e - b * b
            s = np.clip((b * f - c * e) / den, 0, 1) if den > 1e-14 * a * e else 0.0
            t = (b * s + f) / e
            if t < 0:
                t, s = 0.0, np.clip(-c / a, 0, 1)
            elif t > 1:
                t, s = 1.0, np.clip((b - c) / a, 0, 1)
            best = min(best, float(np.linalg.norm(p0 + s * d1 - q0 - t * d2)))
    return best


def crossing(n: int, dt: float, drop: float = 0.03, duration: float = 1.5, shift: float = 0.0, **kw) -> dict:
    """Cable 'low' on the ground along x (centred at the origin), cable 'up' along y, ``drop`` [m] above it;
    ``shift``: the upper cable moved along its axis by this fraction of a segment (0.5 at even n: a node
    right above the lower cable)."""
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    r = spec.diameter / 2
    L = spec.length
    out = {"n": n, "rate": round(1 / dt)}
    with BulletWorld(dt=dt) as world:
        low = world.add_cable(spec, start=(-L / 2, 0, r), direction=(1, 0, 0), name="low", **kw)
        # the upper cable's nodes straddle x = 0 (no node right above the lower cable's axis for even n)
        up = world.add_cable(spec, start=(0.0, -L / 2 + shift * spec.rest_length, 3 * r + drop), direction=(0, 1, 0), name="up", **kw)
        steps = world.steps_in(duration)
        closest = np.inf
        tic = time.perf_counter()
        for k in range(steps):
            world.step()
            if k % 2 == 0:
                closest = min(closest, segment_distance(low.x, up.x))
            if not (low.stable and up.stable):
                break
        out["wall_per_step_us"] = 1e6 * (time.perf_counter() - tic) / (k + 1)
        out["unstable"] = [f"{c.name}: {c.reason} at {c.time_to_instability:.3f} s" for c in (low, up) if not c.stable]
        out["clearance_mm"] = 1e3 * segment_distance(low.x, up.x)
        out["closest_mm"] = 1e3 * closest
        # the upper cable's centre line above the lower one's (y = 0): 3 r = 6 mm resting on it, r through it
        order = np.argsort(up.x[:, 1])
        out["up_mid_z_mm"] = 1e3 * float(np.interp(0.0, up.x[order, 1], up.x[order, 2]))
        out["through"] = bool(out["clearance_mm"] < 1e3 * r)  # both on the ground, one inside the other
        out["speed"] = float(max(np.abs(low.v).max(), np.abs(up.v).max()))
        weight = 2 * spec.mass * 9.81
        support = 0.0
        for c in (low, up):
            cf = c.contact_forces()
            on_ground = cf["body"] == world.ground_id
            support += float(cf["force"][on_ground, 2].sum())
        out["ground_support"] = support / weight if low.model_contact else float("nan")
    return out


def step_cost(n: int, mode: str, rate: float = 240, steps: int = 480) -> float:
    """Wall time per world step [us] (best of 3 x ``steps``, after 0.3 s settling): ``single`` one cable on the
    ground, ``apart`` two cables 0.5 m apart, ``crossing`` the second one resting across the first."""
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    r, L = spec.diameter / 2, spec.length
    with BulletWorld(dt=1 / rate) as w:
        w.add_cable(spec, start=(-L / 2, 0, r), name="low")
        if mode == "crossing":
            w.add_cable(spec, start=(0, -L / 2, 3 * r + 1e-4), direction=(0, 1, 0), name="up")
        elif mode == "apart":
            w.add_cable(spec, start=(-L / 2, 0.5, r), name="far")
        w.run(0.3)
        best = np.inf
        for _ in range(3):
            tic = time.perf_counter()
            w.step(steps)
            best = min(best, (time.perf_counter() - tic) / steps)
    return 1e6 * best


def heavy_on_light(rate: float, times=(0.12, 0.5, 1.5, 3.0)) -> list[str]:
    """A 300 g, 10 mm cable (n 12) across a 10 g, 2 mm one (n 40) on the ground at ``rate`` [Hz]: per time in
    ``times`` [s], the vertical force each feels from the other [N] and the ground's support / both weights."""
    def spec(n, d, m):
        return CableSpec(length=0.3, diameter=d, mass=m, youngs_modulus=126e6, n_masses=n, damping=0.02)

    light, heavy = spec(40, 0.002, 0.01), spec(12, 0.010, 0.3)
    rows = []
    with BulletWorld(dt=1 / rate) as world:
        low = world.add_cable(light, start=(-0.15, 0, 0.001), direction=(1, 0, 0), name="low")
        up = world.add_cable(heavy, start=(0, -0.15, 0.002 + 0.005 + 1e-4), direction=(0, 1, 0), name="up")
        weight = (light.mass + heavy.mass) * 9.81
        for t in times:
            world.run(t - world.time)
            f = {}
            for c in (low, up):
                cf = c.contact_forces()
                f[c.name] = (float(cf["force"][cf["body"] == -2, 2].sum()),
                             float(cf["force"][cf["body"] == world.ground_id, 2].sum()))
            speed = max(np.abs(low.v).max(), np.abs(up.v).max())
            rows.append(f"{rate:>5.0f} {world.time:>6.2f} {f['up'][0]:>+9.3f} {f['low'][0]:>+9.3f} "
                        f"{(f['up'][1] + f['low'][1]) / weight:>8.4f} {speed:>8.1e}")
    return rows


def lying_along(rate: float, n_low: int, n_up: int, d_up: float = 0.004, shift: float = 0.0,
                duration: float = 1.0) -> str:
    """A Lv cable (4 mm, n_low) on the ground along x and one of diameter d_up [m] (n_up) laid along it on top,
    0.1 mm above contact and ``shift`` [m] further along x, after ``duration`` [s] at ``rate`` [Hz]: one row."""
    low_spec = CableSpec.lv2017(n_masses=n_low, damping=0.02)
    up_spec = CableSpec.lv2017(n_masses=n_up, damping=0.02, diameter=d_up)
    length = low_spec.length
    with BulletWorld(dt=1 / rate) as world:
        low = world.add_cable(low_spec, start=(-length / 2, 0, 0.002), direction=(1, 0, 0), name="low")
        up = world.add_cable(up_spec, start=(-length / 2 + shift, 0, 0.004 + d_up / 2 + 1e-4), direction=(1, 0, 0),
                             name="up")
        world.run(duration)
        w_up = up_spec.mass * 9.81
        f = {}
        for c in (low, up):
            cf = c.contact_forces()
            f[c.name] = (float(cf["force"][cf["body"] == -2, 2].sum()), float(cf["force"][cf["body"] == world.ground_id,
                                                                                        2].sum()))
        ground = (f["low"][1] + f["up"][1]) / (w_up + low_spec.mass * 9.81)
        speed = max(np.abs(low.v).max(), np.abs(up.v).max())
        stopped = "; ".join(f"{c.name}: {c.reason}" for c in (low, up) if not c.stable) or "-"
        return (f"{rate:>5.0f} {n_low:>5} {n_up:>4} {1e3 * d_up:>5.1f} {1e3 * shift:>6.1f} {f['up'][0] / w_up:>+8.4f} "
                f"{f['low'][0] / w_up:>+9.4f} {ground:>8.4f} {speed:>8.1e}  {stopped}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drop", type=float, default=0.03)
    ap.add_argument("--duration", type=float, default=1.5)
    ap.add_argument("--n", type=int, nargs="+", default=[10, 20, 40])
    ap.add_argument("--shift", type=float, default=0.0)
    ap.add_argument("--rates", type=float, nargs="+", default=[60, 240, 1000])
    ap.add_argument("--cost", action="store_true", help="time a world step instead (240 Hz, n from --n)")
    ap.add_argument("--heavy", action="store_true", help="a heavy cable across a light one instead (see above)")
    ap.add_argument("--along", action="store_true", help="a cable lying along another one instead (see above)")
    a = ap.parse_args()
    if a.along:
        print(f"{'rate':>5} {'n low':>5} {'n up':>4} {'d mm':>5} {'shift':>6} {'on up/W':>8} {'on low/W':>9} "
              f"{'ground/W':>8} {'|v| max':>8}  stopped")
        for rate in a.rates:
            cases = [(n, n, 0.004, 0.0) for n in a.n] + [(a.n[0], a.n[-1], 0.004, 0.0), (a.n[-1], a.n[0], 0.006, 0.01)]
            for n_low, n_up, d_up, shift in cases:
                print(lying_along(rate, n_low, n_up, d_up, shift), flush=True)
        return
    if a.heavy:
        print(f"{'rate':>5} {'t s':>6} {'on up N':>9} {'on low N':>9} {'ground/W':>8} {'|v| max':>8}")
        for rate in a.rates:
            print("\n".join(heavy_on_light(rate)), flush=True)
        return
    if a.cost:
        for n in a.n:
            one, apart, cross = (step_cost(n, m) for m in ("single", "apart", "crossing"))
            print(f"n = {n}: one cable {one:.0f} us/step; two apart {apart:.0f} ({apart / one:.2f}x); "
                  f"two crossing {cross:.0f} ({cross / one:.2f}x one, {cross / apart:.2f}x two apart)", flush=True)
        return
    print(f"{'rate':>5} {'n':>3} {'clear mm':>9} {'closest mm':>10} {'up z at x mm':>12} {'through':>7} "
          f"{'|v| max':>8} {'ground/W':>8} {'us/step':>8}  unstable")
    for rate in a.rates:
        for n in a.n:
            o = crossing(n, 1 / rate, a.drop, a.duration, a.shift)
            print(f"{o['rate']:>5} {n:>3} {o['clearance_mm']:>9.3f} {o['closest_mm']:>10.3f} {o['up_mid_z_mm']:>12.3f} "
                  f"{str(o['through']):>7} {o['speed']:>8.2e} {o['ground_support']:>8.4f} {o['wall_per_step_us']:>8.0f}  "
                  f"{'; '.join(o['unstable']) or '-'}", flush=True)


if __name__ == "__main__":
    main()
