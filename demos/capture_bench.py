"""Dataset capture throughput and file sizes.

Captures 2-s dual-arm episodes at 240 Hz (the randomisation of ``demos/specs/dr_small.yaml``
with the step fixed) with 1 and 2 workers after a warm-up, and once more with frames
(160x120 at 10 fps) to compare file sizes. Prints episodes per second and the speed-up, and
writes ``capture_bench.json`` into the output folder (captures go to sub-folders).

Usage: ``python demos/capture_bench.py [--out DIR] [--episodes 8]``
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
from pathlib import Path

import yaml

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.data.capture import capture

SPEC = Path(__file__).resolve().parent / "specs" / "dr_small.yaml"


def spec(frames: bool) -> CaptureSpec:
    data = yaml.safe_load(SPEC.read_text())
    data["episode"]["duration"] = 2.0
    data["sample"]["dt"] = {"dist": "fixed", "value": 1.0 / 240.0}
    data["camera"] = {"fps": 10, "width": 160, "height": 120} if frames else {"fps": 0}
    return CaptureSpec.from_dict(data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "capture_bench"), help="output folder")
    parser.add_argument("--episodes", type=int, default=8, help="episodes per capture")
    args = parser.parse_args()
    out = Path(args.out)
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    capture(spec(False), out / "warmup", 2, workers=2, progress=False)  # compile caches in workers
    result = {}
    for workers in (1, 2):
        res = capture(spec(False), out / f"w{workers}", args.episodes, workers=workers, progress=False)
        result[f"episodes_per_s_{workers}_workers"] = res.episodes_per_second
        print(f"{workers} worker(s): {res.ran} episodes in {res.wall_time_s:.1f} s = "
              f"{res.episodes_per_second:.2f} episodes/s")
    result["speedup_2_vs_1"] = result["episodes_per_s_2_workers"] / result["episodes_per_s_1_workers"]
    capture(spec(True), out / "frames", 2, workers=2, progress=False)
    plain = [p.stat().st_size for p in (out / "w1").glob("episode_*.h5")]
    framed = [p.stat().st_size for p in (out / "frames").glob("episode_*.h5")]
    result["bytes_per_episode"] = statistics.median(plain)
    result["bytes_per_episode_with_frames"] = statistics.median(framed)
    print(f"speed-up with 2 workers: {result['speedup_2_vs_1']:.2f}x")
    print(f"file size per 2-s episode: {result['bytes_per_episode'] / 1e3:.0f} kB; with 160x120 frames at 10 fps: "
          f"{result['bytes_per_episode_with_frames'] / 1e3:.0f} kB")
    (out / "capture_bench.json").write_text(json.dumps(result, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
