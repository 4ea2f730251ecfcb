"""Peak memory and time of exporting a 10-minute 5 kHz recording (3 M frames) to CSV.

A child process writes the recording (project HDF5 layout, all RECORD_CHANNELS, simulated-like
signals); a second, fresh child process runs :func:`rigd.data.export.export_csv` on it and
reports its own peak resident memory (``VmHWM``) and wall time. Bound: 200 MB.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

N_FRAMES = 3_000_000      # 10 min at 5 kHz
FS = 5000.0

MAKE = r"""
import sys, numpy as np, h5py
from rigd.frame import RECORD_NAMES, REC
path, n, fs = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
C = len(RECORD_NAMES)
rng = np.random.default_rng(1)
with h5py.File(path, "w", libver="latest") as f:
    ds = f.create_dataset("frames", shape=(n, C), maxshape=(None, C), chunks=(4096, C), dtype="f8")
    ds.attrs["channels"] = list(RECORD_NAMES)
    f.attrs.update({"fs": fs, "omega_rpm": 3000.0, "p_inj_bar": 4.0, "kind": "prbs"})
    step = 100_000
    for s in range(0, n, step):
        m = min(step, n - s)
        seq = np.arange(s, s + m, dtype=float)
        t = seq / fs
        blk = rng.standard_normal((m, C)) * 0.01
        blk[:, REC["seq"]] = seq
        blk[:, REC["t"]] = t
        blk[:, REC["phi"]] = np.mod(2 * np.pi * 50.0 * t, 2 * np.pi)
        blk[:, REC["e_x"]] += 5 * np.sin(2 * np.pi * 50 * t)
        blk[:, REC["f_x"]] = 0.0
        blk[:, REC["f_y"]] = 0.0
        blk[:, REC["omega_rpm"]] = 3000.0
        blk[:, REC["p_inj_bar"]] = 4.0
        blk[:, REC["k_on"]] = 1.0
        blk[:, REC["fault"]] = 0.0
        ds[s:s + m] = blk
"""

# Peak resident memory from /proc/self/status VmHWM: it belongs to this process's own address
# space (reset by execve). getrusage's ru_maxrss is NOT reset by execve on Linux, so a child
# forked from a large parent (the bench process after other sections) would report the
# parent's size.
EXPORT = r"""
import json, sys, time
def hwm_mb():
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
from rigd.data.export import export_csv
base = hwm_mb()
t0 = time.perf_counter()
rows = export_csv(sys.argv[1], sys.argv[2])
dt = time.perf_counter() - t0
peak = hwm_mb()
print(json.dumps({"rows": rows, "export_s": dt, "peak_mb": peak, "base_mb": base}))
"""


def run(n_frames: int = N_FRAMES) -> dict:
    with tempfile.TemporaryDirectory(prefix="rigd-bench-export-") as tmp:
        h5 = Path(tmp) / "rec.h5"
        out = Path(tmp) / "rec.csv"
        subprocess.run([sys.executable, "-c", MAKE, str(h5), str(n_frames), str(FS)],
                       check=True)
        proc = subprocess.run([sys.executable, "-c", EXPORT, str(h5), str(out)], check=True,
                              capture_output=True, text=True)
        res = json.loads(proc.stdout.strip().splitlines()[-1])
        size_mb = out.stat().st_size / 2 ** 20
    assert res["rows"] == n_frames
    return {
        "export_frames": n_frames,
        "export_peak_mb": round(res["peak_mb"], 1),
        "export_import_baseline_mb": round(res["base_mb"], 1),
        "export_s": round(res["export_s"], 1),
        "export_csv_mb": round(size_mb, 1),
        "export_peak_under_200mb": res["peak_mb"] < 200.0,
    }


if __name__ == "__main__":
    print(json.dumps(run(int(sys.argv[1]) if len(sys.argv) > 1 else N_FRAMES)))
