"""Which damping law the beam_handling strip's decays follow, from the recordings alone (no simulation).

Per recording: the decay envelope of the most affected joint from end + 1 s to the recording's end (sines at the
measured frequency over two-cycle windows one cycle apart), the local damping ratio over spans of 3 cycles against
the strip's tip amplitude, and four laws fitted to the envelope (zeta0; zeta0 + c A; zeta0 + b / A;
zeta_ref (A / A_ref)^p) with their relative misfit and Akaike criterion. Then the laws fitted across files in tip
amplitude (bullet_dlo.reality.beam_law: the first mode's clamp load through J^T and Franka's filter, no model run):
on all nine, on the X and on the Z files; the face-drag coefficient the shared slope asks for; and how much of the
between-file spread of the 1-6 s damping ratio (the issue's metric) the shared law explains.

    python demos/beam_damping_law.py ../shared/data/beam_handling
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from bullet_dlo.reality.beam import beam_files, read_beam_csv
from bullet_dlo.reality.beam_law import file_decay, law_drag_coefficient, law_window_ratio, shared_laws
from bullet_dlo.reality.beam_validate import measure
from bullet_dlo.reality.panda import Panda
from bullet_dlo.reality.vibration import DECAY_LAWS, best_decay_law


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="folder of beam_handling *.csv recordings")
    args = parser.parse_args()
    recs = [read_beam_csv(p) for p in beam_files(args.folder)]
    with Panda() as panda:
        decays = [file_decay(r, panda) for r in recs]
    print("per file (torque units; c in 1/(N m), b in N m; tip amplitudes from the modal clamp load):")
    for d in decays:
        f = d.fits
        print(f"{d.name:24s} j{d.joint} {d.torque_per_tip:5.1f} N m/m  tip {1e3 * d.tip_amplitude[0]:5.1f} -> "
              f"{1e3 * d.tip_amplitude[-1]:4.1f} mm  best {best_decay_law(f):8s} "
              f"rms_log viscous {f['viscous'].rms_log:.3f} drag {f['drag'].rms_log:.3f} friction "
              f"{f['friction'].rms_log:.3f}  dAIC(drag-viscous) {f['drag'].aic - f['viscous'].aic:6.1f}  "
              f"p {f['power'].params['p']:5.2f}  drag: zeta0 {f['drag'].params['zeta0']:.4f} "
              f"c {f['drag'].params['c'] * d.torque_per_tip:.3f}/m  friction b {f['friction'].params['b']:.2g}")
        print("    local zeta at tip amplitude [mm]: "
              + "  ".join(f"{1e3 * a:.0f}: {z:.4f}" for a, z in d.local))
    groups = {"all nine": decays, "X (6)": [d for d in decays if "_X" in d.name],
              "Z (3)": [d for d in decays if "_Z" in d.name]}
    measured = {r.name: measure(r).vibration.damping_ratio for r in recs}
    for name, g in groups.items():
        fits = shared_laws(g)
        per_file_aic = sum(d.fits[best_decay_law(d.fits)].aic for d in g)
        print(f"\nshared across {name}: best {best_decay_law(fits)} (per-file laws' AIC sum {per_file_aic:.0f})")
        for law in DECAY_LAWS:
            p = ", ".join(f"{k} {v:.4g}" for k, v in fits[law].params.items())
            print(f"  {law:8s} {p:48s} rms_log {fits[law].rms_log:.3f}  AIC {fits[law].aic:7.1f}  "
                  f"({fits[law].points} points)")
        print(f"  drag law slope -> face drag C_d = {law_drag_coefficient(fits['drag']):.1f}")
        if name == "all nine":
            zl = {d.name: law_window_ratio(fits["drag"], d) for d in g}
            zv = np.array([measured[d.name] for d in g])
            zp = np.array([zl[d.name] for d in g])
            print("  1-6 s damping ratio, measured / shared drag law / ratio: " + ", ".join(
                f"{d.name[4:-3]} {a:.4f}/{b:.4f}/{b / a:.2f}" for d, a, b in zip(g, zv, zp)))
            print(f"  between-file spread of the measured 1-6 s damping ratio explained by the law: "
                  f"{1 - np.var(zv - zp) / np.var(zv):.2f} (correlation {np.corrcoef(zv, zp)[0, 1]:.2f}); "
                  f"within 30 %: {int(np.sum(np.abs(zp / zv - 1) <= 0.3))} of {len(g)}")
    print("\nheld out: the drag law fitted on one folder, the other folder's 1-6 s damping ratio (ratio law / measured):")
    for fit_name, pred_name in (("X (6)", "Z (3)"), ("Z (3)", "X (6)")):
        law = shared_laws(groups[fit_name])["drag"]
        ratios = [law_window_ratio(law, d) / measured[d.name] for d in groups[pred_name]]
        print(f"  {fit_name} -> {pred_name}: " + ", ".join(f"{d.name[4:-3]} {r:.2f}" for d, r in
                                                          zip(groups[pred_name], ratios))
              + f"; within 30 %: {sum(abs(r - 1) <= 0.3 for r in ratios)} of {len(ratios)}")


if __name__ == "__main__":
    main()
