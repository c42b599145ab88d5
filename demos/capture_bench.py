"""Dataset capture throughput and file sizes.

Captures 2-s dual-arm episodes at 240 Hz (the randomisation of ``demos/specs/dr_small.yaml``
with the step fixed) with 1 and 2 workers after a warm-up, and once more with frames
(160x120 at 10 fps) to compare file sizes. Prints episodes per second and the speed-up, and
writes ``capture_bench.json`` into the output folder (captures go to sub-folders).

Usage: ``python demos/capture_bench.py [--out DIR] [--episodes 8] [--quick]`` (``--quick``: 2 episodes
of 0.3 s each, for a smoke test; the numbers then say nothing about throughput).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
from pathlib import Path

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.loader import load_yaml
from bullet_dlo.data import capture

SPEC = Path(__file__).resolve().parent / "specs" / "dr_small.yaml"


def spec(frames: bool, duration: float) -> CaptureSpec:
    """The demo's spec with episodes of ``duration`` [s] at 240 Hz, with or without frames."""
    data = load_yaml(SPEC, "capture spec")
    data["episode"]["duration"] = duration
    data["sample"]["dt"] = {"dist": "fixed", "value": 1.0 / 240.0}
    data["camera"] = {"fps": 10, "width": 160, "height": 120} if frames else {"fps": 0}
    return CaptureSpec.from_dict(data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "capture_bench"), help="output folder")
    parser.add_argument("--episodes", type=int, default=8, help="episodes per capture")
    parser.add_argument("--quick", action="store_true", help="2 short episodes per capture (smoke test)")
    args = parser.parse_args()
    episodes, duration = (2, 0.3) if args.quick else (args.episodes, 2.0)
    out = Path(args.out)
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    if not args.quick:
        capture(spec(False, duration), out / "warmup", 2, workers=2, progress=False)  # compile caches in workers
    result = {}
    for workers in (1, 2):
        res = capture(spec(False, duration), out / f"w{workers}", episodes, workers=workers, progress=False)
        result[f"episodes_per_s_{workers}_workers"] = res.episodes_per_second
        print(f"{workers} worker(s): {res.ran} episodes in {res.wall_time_s:.1f} s = "
              f"{res.episodes_per_second:.2f} episodes/s")
    result["speedup_2_vs_1"] = result["episodes_per_s_2_workers"] / result["episodes_per_s_1_workers"]
    capture(spec(True, duration), out / "frames", 2, workers=2, progress=False)
    plain = [p.stat().st_size for p in (out / "w1").glob("episode_*.h5")]
    framed = [p.stat().st_size for p in (out / "frames").glob("episode_*.h5")]
    result["bytes_per_episode"] = statistics.median(plain)
    result["bytes_per_episode_with_frames"] = statistics.median(framed)
    print(f"speed-up with 2 workers: {result['speedup_2_vs_1']:.2f}x")
    print(f"file size per {duration:g}-s episode: {result['bytes_per_episode'] / 1e3:.0f} kB; "
          f"with 160x120 frames at 10 fps: {result['bytes_per_episode_with_frames'] / 1e3:.0f} kB")
    (out / "capture_bench.json").write_text(json.dumps(result, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
