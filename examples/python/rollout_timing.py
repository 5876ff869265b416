"""Times Scene.simulate from Python: the counterpart of crates/diffsoft/examples/rollout_timing.rs, which times
the library's rollout on the same scene from Rust. The ratio of the two medians is the cost of the
Python layer (arguments, the GIL release, numpy arrays of the trajectory, the run log as a dict).

    python examples/python/rollout_timing.py [SCENE] [STEPS] [REPEATS]
"""

import sys
import time
from pathlib import Path

import diffsoft

REPO = Path(__file__).resolve().parents[2]


def main() -> None:
    path = sys.argv[1] if len(sys.argv) > 1 else str(REPO / "verification/scenes/baymax_skeleton.json")
    steps = int(sys.argv[2]) if len(sys.argv) > 2 else 100
    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 15
    scene = diffsoft.Scene.load(path)
    scene.simulate(steps)  # untimed: warms caches and the thread pool
    ms = []
    for _ in range(repeats):
        t = time.perf_counter()
        run = scene.simulate(steps)
        ms.append((time.perf_counter() - t) * 1e3)
        if run.stats["unconverged_steps"]:
            raise SystemExit(f"{path}: the rollout did not converge")
    ms.sort()
    print(
        f"python {path}: {steps} steps, median {ms[repeats // 2]:.2f} ms over {repeats} rollouts "
        f"(min {ms[0]:.2f}, max {ms[-1]:.2f})"
    )


if __name__ == "__main__":
    main()
