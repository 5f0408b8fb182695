"""Native SIL benchmark: speed against real time, and determinism.

Run: .venv/bin/python bench/bench_sil.py   (prints the figures; numbers depend on the machine)

1. firmware alone: 60 s of the real firmware (libagnav_sil.so, 100 us loop ticks), no world;
2. firmware + world: 60 s of the lock-step SIL (robot model, encoder edges, 12-sonar echoes,
   radio link model, host endpoint decoding all telemetry), host = follow-wall enable + heartbeats
   (no laser planner), hil/tests/scenarios/wall_corridor.toml;
3. full stack: corridor_obstacles with the goal_seek host planner on the TiM561 laser (811 beams,
   15 Hz), 60 s or until arrival;
4. the ideal runner (no firmware) on the same scenario, for reference;
5. determinism: two runs with the same seed (5 % frame loss both ways) -> SHA-256 of link.tlog.

The lock-step lines also give the process CPU time: on a loaded machine (other jobs on the same
cores) the wall time includes waiting for a core, the CPU time does not.
"""

from __future__ import annotations

import hashlib
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def best_of(fn, n: int = 3) -> float:
    return min(fn() for _ in range(n))


def main() -> int:
    from agnav_host.sil import Firmware, LinkParams, SilConfig, SilSession, build_library, run_sil_scenario
    from agnav_host.sim import load_scenario, run_scenario

    build_library()

    def fw_alone() -> float:
        with Firmware() as fw:
            fw.set_stop_on_trigger(False)
            t = time.perf_counter()
            fw.step_us(60_000_000)
            return time.perf_counter() - t

    w1 = best_of(fw_alone)
    print(f"firmware alone, 60 s simulated (600000 loop passes): {w1 * 1e3:.1f} ms wall -> {60 / w1:.0f}x real time")

    class Hb:
        def __init__(self) -> None:
            self.next, self.on = 0, False

        def __call__(self, s: SilSession, t: int) -> None:
            if not self.on:
                s.host.set_behaviours(True)
                self.on = True
            if t >= self.next:
                s.host.heartbeat()
                self.next += 200_000

    sc_w = load_scenario(str(REPO / "hil/tests/scenarios/wall_corridor.toml"))

    def fw_world(dt: float, cpu: list[float]):
        def go() -> float:
            s = SilSession(sc_w, 0, SilConfig(world_dt_s=dt), Hb())
            s.provision()
            c = time.process_time()
            t = time.perf_counter()
            s.run_for(60.0)
            w = time.perf_counter() - t
            cpu.append(time.process_time() - c)
            s.close()
            return w
        return go

    for dt in (0.02, 0.01, 0.005):
        cpu: list[float] = []
        w2 = best_of(fw_world(dt, cpu), 5)
        c2 = min(cpu)
        print(f"firmware + world + link + host endpoint, 60 s, world step {dt * 1e3:.0f} ms: {w2:.3f} s wall -> "
              f"{60 / w2:.0f}x real time (process CPU {c2:.3f} s -> {60 / c2:.0f}x)")

    sc = load_scenario("corridor_obstacles")
    res = [run_sil_scenario(sc, "goal_seek", 0, 60.0) for _ in range(3)]
    r = min(res, key=lambda x: x.wall_s)
    print(f"full stack (goal_seek on 811-beam laser at 15 Hz), corridor_obstacles: {r.run.metrics.time_s:.1f} s simulated "
          f"({r.run.end_reason}) in {r.wall_s:.3f} s wall -> {r.run.metrics.time_s / r.wall_s:.0f}x real time")
    ideal = []
    for _ in range(3):
        t = time.perf_counter()
        ri = run_scenario(sc, "goal_seek", 0, 60.0)
        ideal.append((time.perf_counter() - t, ri))
    wi, ri = min(ideal, key=lambda x: x[0])
    print(f"ideal runner (no firmware), same scenario: {ri.metrics.time_s:.1f} s simulated ({ri.end_reason}) in "
          f"{wi:.3f} s wall -> {ri.metrics.time_s / wi:.0f}x real time")

    lossy = LinkParams(loss=0.05)
    cfg = SilConfig(uplink=lossy, downlink=lossy)
    runs = [run_sil_scenario(sc, "goal_seek", 11, 60.0, config=cfg) for _ in range(2)]
    h = [hashlib.sha256(x.tlog).hexdigest() for x in runs]
    print(f"determinism: seed 11, 5 % loss: tlog {len(runs[0].tlog)} B, sha256 {h[0][:16]} / {h[1][:16]} -> "
          f"{'identical' if h[0] == h[1] else 'DIFFERENT'}; link {runs[0].link_stats}")
    return 0 if h[0] == h[1] else 1


if __name__ == "__main__":
    sys.exit(main())
