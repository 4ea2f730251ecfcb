"""Figures of the simulated plant for docs/plant.md: ``python -m rigd_drivers.sim.info``.

Prints (as JSON) the mode table over the operating grid, the valve closed-loop step figures
under the suggested PD gains, the change each hidden effect makes to an identification
record, and the kernel's time per step.
"""

from __future__ import annotations

import json
import time

import numpy as np

from rigd.frame import IN_YP1, N_IN
from rigd_drivers.plant import physics as phys
from rigd_drivers.sim import kernel as k
from rigd_drivers.sim.driver import SimPlantDriver

QUIET = {"noise": {"e_um": 0.0, "y_p_v": 0.0}}


def run_pd(driver: SimPlantDriver, r_p: np.ndarray, kp: float = phys.PD_KP,
           kd: float = phys.PD_KD, tau: float = phys.PD_TAU_D,
           kff: float = phys.PD_KFF) -> np.ndarray:
    """Run ``driver`` under four PD loops as ``rigd.loop.cycle.pd_step`` does.

    Feed-forward, derivative of the error filtered by backward Euler, drive clamped to
    [0, 10] V; per-valve references ``r_p`` (n, 4) V. Returns the frames (n, N_IN): row i is
    the sample after step i. Plain Python (≈ 10 µs per step): for studies, not for the loop.
    """
    T = 1.0 / driver.fs
    n = r_p.shape[0]
    frames = np.zeros((n, N_IN))
    f = np.zeros(N_IN)
    driver.read(f)
    eprev = r_p[0] - f[IN_YP1:IN_YP1 + 4]
    d = np.zeros(4)
    drive = np.zeros(4)
    for i in range(n):
        e = r_p[i] - f[IN_YP1:IN_YP1 + 4]
        d = (tau * d + (e - eprev)) / (tau + T)
        eprev = e
        drive[:] = np.clip(kff * r_p[i] + kp * e + kd * d, 0.0, 10.0)
        driver.write(drive)
        driver.read(f)
        frames[i] = f
    return frames


def mode_table() -> list[dict]:
    rows = []
    for p in (3.0, 4.0, 5.0, 7.0):
        for om in (0.0, 3000.0, 6000.0):
            f, z = phys.bearing_modes(om, p)
            rows.append({"p_inj_bar": p, "omega_rpm": om, "f_hz": [round(x, 1) for x in f],
                         "zeta": [round(x, 4) for x in z]})
    return rows


def effect_strength(n: int = 5000) -> dict[str, list[float]]:
    """RMS change of [e_x, e_y, u_x, u_y] made by each effect alone, relative to the RMS of
    the record without it (PD loops, Ω = 3000 rpm, 4 bar, PRBS ±1 V held 1 ms; creep also on
    multi-level steps held 0.1 s)."""
    out = {}
    for name, hold in [("delay", 5), ("cubic_stiffness", 5), ("extra_mode", 5),
                       ("hysteresis", 5), ("runout", 5), ("creep", 5), ("creep", 500)]:
        rng = np.random.default_rng(1)
        lv = np.repeat(rng.uniform(-1, 1, size=(n // hold + 1, 2)), hold, axis=0)[:n]
        if hold == 5:
            lv = np.sign(lv)
        r = np.column_stack([5 + lv[:, 1], 5 + lv[:, 0], 5 - lv[:, 1], 5 - lv[:, 0]])
        opts = {**QUIET, "omega_rpm": 3000.0}

        def ch(f):
            y = f[:, IN_YP1:IN_YP1 + 4]
            return np.column_stack([f[:, 0], f[:, 1], y[:, 1] - y[:, 3], y[:, 0] - y[:, 2]])

        b = ch(run_pd(SimPlantDriver(opts), r))
        e = ch(run_pd(SimPlantDriver({**opts, "effects": {name: {"enabled": True}}}), r))
        key = name if hold == 5 else f"{name}_multilevel"
        out[key] = [round(float(x), 3) for x in (e - b).std(axis=0) / b.std(axis=0)]
    return out


def kernel_us_per_step(n: int = 200_000, repeat: int = 5) -> dict[str, float]:
    """Best-of-``repeat`` time per ``plant_step`` (µs), compiled batch, several set-ups."""
    out = {}
    for label, opts in [("no_noise", QUIET), ("default", {}),
                        ("cubic_stiffness", {"effects": {"cubic_stiffness": {"enabled": True}}}),
                        ("all_effects", {"omega_rpm": 3000.0, "effects": {
                            e: {"enabled": True} for e in ("delay", "cubic_stiffness",
                                                           "extra_mode", "hysteresis",
                                                           "creep", "runout")}})]:
        d = SimPlantDriver(opts)
        drives = np.full((n, 4), 5.0)
        frames = np.zeros((n, N_IN))
        k.run_batch(d.state, d.params, drives[:10], frames[:10])
        best = np.inf
        for _ in range(repeat):
            t = time.perf_counter()
            k.run_batch(d.state, d.params, drives, frames)
            best = min(best, (time.perf_counter() - t) / n * 1e6)
        out[label] = round(best, 3)
    return out


def main() -> None:
    valves = [{"valve": i + 1, **{a: round(b, 5) for a, b in
                                  phys.step_metrics(phys.valve_closed_loop(v)).items()}}
              for i, v in enumerate(phys.valve_params())]
    lumped = {a: {x: round(y, 5) for x, y in phys.step_metrics(phys.lumped_actuator_tf(a)).items()}
              for a in ("x", "y")}
    print(json.dumps({"modes": mode_table(), "valves_pd": valves, "lumped_pd": lumped,
                      "effect_strength": effect_strength(),
                      "plant_step_us": kernel_us_per_step()}, indent=1))


if __name__ == "__main__":
    main()
