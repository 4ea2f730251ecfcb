"""Operating range: identify every grid point of a sweep and reassemble G_bear(Ω, P_I).

``rigd identify RUN_DIR`` reads ``RUN_DIR/manifest.json`` (written by ``rigd experiment``,
format ``rigd_manifest: 1``). What is used, read defensively:

* ``files``: a list of ``{"path", "kind", "omega_rpm", "p_inj_bar"}``; ``path`` relative to
  RUN_DIR. Records of kind ``prbs`` (or no kind) are identified; a record of kind ``runout`` at
  the same (Ω, P_I) is used as its run-out record; other kinds (``impact`` ...) are ignored.
  Files that do not exist are reported and skipped.

Grid points are fitted in parallel (``concurrent.futures.ProcessPoolExecutor``, one process per
core by default). The result is a parameter table versus (Ω, P_I), plots, and a
:class:`ReassembledBearing` whose :meth:`~ReassembledBearing.at` interpolates the bearing
parameters (K, D, B of Eq. 6) linearly between grid points (clipped to the grid's range) and
returns a python-control StateSpace, saved as one YAML file (``rigd_gbear: 1``).
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rigd.configio import dump_yaml, read_yaml
from rigd.errors import InputError
from rigd.ident.greybox.rotor import bearing_structure

OP_TOL = (50.0, 0.1)  # rpm, bar: same operating point


def _same(a, b) -> bool:
    return abs(a[0] - b[0]) <= OP_TOL[0] and abs(a[1] - b[1]) <= OP_TOL[1]


def sweep_jobs(run_dir: str | Path) -> tuple[list[dict], list[str]]:
    """(jobs, notes): one job per identification record with its run-out record if any."""
    from rigd.data.manifest import read_manifest

    run_dir = Path(run_dir)
    man = read_manifest(run_dir)
    files = man.get("files")
    if not isinstance(files, list) or not files:
        raise InputError("manifest lists no record files", str(run_dir / "manifest.json"))
    notes, recs, runouts = [], [], []
    for i, f in enumerate(files):
        if not isinstance(f, dict) or "path" not in f:
            notes.append(f"files[{i}]: no path, skipped")
            continue
        try:
            op = (float(f.get("omega_rpm", 0.0) or 0.0), float(f["p_inj_bar"]))
        except (KeyError, TypeError, ValueError):
            notes.append(f"{f['path']}: no numeric omega_rpm/p_inj_bar, skipped")
            continue
        p = run_dir / f["path"]
        if not p.exists():
            notes.append(f"{f['path']}: listed but missing, skipped")
            continue
        kind = (f.get("kind") or "prbs").lower()
        if kind == "runout":
            runouts.append((op, str(p)))
        elif kind in ("prbs", "free", "ident", "identification"):
            recs.append((op, str(p)))
    if not recs:
        raise InputError("manifest lists no identification (prbs) records that exist",
                         str(run_dir / "manifest.json"))
    jobs = []
    for op, p in recs:
        ro = next((r for o, r in runouts if _same(o, op)), None)
        jobs.append({"path": p, "runout": ro, "omega_rpm": op[0], "p_inj_bar": op[1]})
    return jobs, notes


def _fit_point(job: dict) -> dict:
    """Worker: identify one grid point (runs in a child process)."""
    from rigd.data.io import load_record
    from rigd.ident.prefilter import PrefilterOptions
    from rigd.ident.workflow import identify_record

    try:
        rec = load_record(job["path"])
        ro = load_record(job["runout"]) if job.get("runout") else None
        model = identify_record(rec, "bearing", runout=ro,
                                options=PrefilterOptions(**job.get("options", {})),
                                method=job.get("method", "auto"), split=job.get("split", 2 / 3))
        sm = model.submodels["bearing"]
        return {**job, "ok": True, "parameters": sm.parameters,
                "std": dict(zip(sm.structure.names, map(float, sm.std))),
                "fit_percent": sm.fit_percent["validation_mean"],
                "modes": sm.readouts.get("modes", []), "fs": model.fs}
    except InputError as exc:
        return {**job, "ok": False, "error": str(exc)}


class ReassembledBearing:
    """G_bear(Ω, P_I): bearing models interpolated between identified grid points.

    Parameters
    ----------
    points : ndarray (m, 2)
        (Ω in rpm, P_I in bar) of the grid points.
    thetas : ndarray (m, 20)
        Bearing parameters (``bearing_structure().names`` order) at each point.
    fs : float
        Sample rate of the data they came from, Hz.
    """

    def __init__(self, points, thetas, fs: float, fits=None):
        self.points = np.asarray(points, float).reshape(-1, 2)
        self.thetas = np.asarray(thetas, float).reshape(len(self.points), -1)
        self.fs = float(fs)
        self.fits = list(fits) if fits is not None else [None] * len(self.points)
        self.structure = bearing_structure()
        if self.thetas.shape[1] != len(self.structure.names):
            raise InputError(f"G_bear needs {len(self.structure.names)} parameters per point")
        self._interp = self._build()

    def _build(self):
        from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator

        P, T = self.points, self.thetas
        lo, hi = P.min(axis=0), P.max(axis=0)
        varying = [i for i in range(2) if hi[i] - lo[i] > 0]
        if len(P) == 1 or not varying:
            return lambda q: T[0]
        if len(varying) == 1:
            i = varying[0]
            order = np.argsort(P[:, i])
            x = P[order, i]
            return lambda q: np.array([np.interp(q[i], x, T[order, j]) for j in range(T.shape[1])])
        span = np.where(hi > lo, hi - lo, 1.0)
        Pn = (P - lo) / span
        try:
            lin = LinearNDInterpolator(Pn, T)
        except Exception:  # noqa: BLE001 - collinear points
            lin = None
        near = NearestNDInterpolator(Pn, T)

        def f(q):
            qn = (np.clip(q, lo, hi) - lo) / span
            v = lin(qn[None, :])[0] if lin is not None else np.full(T.shape[1], np.nan)
            return v if np.all(np.isfinite(v)) else near(qn[None, :])[0]

        return f

    def theta(self, omega_rpm: float, p_inj_bar: float) -> np.ndarray:
        """Interpolated bearing parameters at (Ω rpm, P_I bar), clipped to the grid."""
        return np.asarray(self._interp(np.array([omega_rpm, p_inj_bar], float)), float)

    def at(self, omega_rpm: float, p_inj_bar: float):
        """Continuous python-control StateSpace u -> p of the bearing at (Ω, P_I)."""
        return self.structure.ss(self.theta(omega_rpm, p_inj_bar))

    def modes(self, omega_rpm: float, p_inj_bar: float):
        return self.structure.modes(self.theta(omega_rpm, p_inj_bar))

    def save(self, path: str | Path) -> None:
        """Write the ``rigd_gbear: 1`` YAML atomically."""
        names = self.structure.names
        dump_yaml(path, {"rigd_gbear": 1, "fs_hz": self.fs, "structure": "bearing",
                         "points": [{"omega_rpm": float(p[0]), "p_inj_bar": float(p[1]),
                                     "fit_percent": None if f is None else float(f),
                                     "parameters": {n: float(v) for n, v in zip(names, t)}}
                                    for p, t, f in zip(self.points, self.thetas, self.fits)]})

    @classmethod
    def load(cls, path: str | Path) -> ReassembledBearing:
        doc = read_yaml(path).data
        if not isinstance(doc, dict) or doc.get("rigd_gbear") != 1:
            raise InputError("not a G_bear file (rigd_gbear: 1 missing)", str(path))
        names = bearing_structure().names
        try:
            pts = [(p["omega_rpm"], p["p_inj_bar"]) for p in doc["points"]]
            th = [[p["parameters"][n] for n in names] for p in doc["points"]]
            fits = [p.get("fit_percent") for p in doc["points"]]
            return cls(pts, th, float(doc["fs_hz"]), fits)
        except (KeyError, TypeError) as exc:
            raise InputError(f"malformed G_bear file: missing {exc}", str(path)) from None


@dataclass
class SweepResult:
    """Per-point results, the reassembled model and where things were written."""

    points: list[dict]
    gbear: ReassembledBearing | None
    notes: list[str] = field(default_factory=list)
    files: dict[str, str] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        ok = [p for p in self.points if p["ok"]]
        return {"fit_percent": {f"{p['omega_rpm']:g}rpm_{p['p_inj_bar']:g}bar": p["fit_percent"]
                                for p in ok},
                "parameters": {f"{p['omega_rpm']:g}rpm_{p['p_inj_bar']:g}bar": p["parameters"]
                               for p in ok},
                "effects": [], "points": [{k: p.get(k) for k in ("omega_rpm", "p_inj_bar", "ok",
                                                                  "fit_percent", "modes", "error")}
                                          for p in self.points],
                "notes": self.notes, "files": self.files}

    def text(self) -> str:
        lines = ["omega_rpm  p_inj_bar  fit%   modes (f_n Hz / zeta)"]
        for p in sorted(self.points, key=lambda p: (p["p_inj_bar"], p["omega_rpm"])):
            if not p["ok"]:
                lines.append(f"{p['omega_rpm']:9g}  {p['p_inj_bar']:9g}  failed: {p['error']}")
                continue
            ms = "  ".join(f"{m['f_n_hz']:.1f}/{m['zeta']:.3f}" for m in p["modes"]
                           if "f_n_hz" in m)
            lines.append(f"{p['omega_rpm']:9g}  {p['p_inj_bar']:9g}  {p['fit_percent']:5.1f}  {ms}")
        lines += [f"note: {n}" for n in self.notes]
        lines += [f"{k}: {v}" for k, v in self.files.items()]
        return "\n".join(lines)


def identify_sweep(run_dir, out=None, jobs: int | None = None, method: str = "auto",
                   options=None, split: float = 2 / 3) -> SweepResult:
    """Identify every grid point of a sweep run directory in parallel (see module doc)."""
    job_list, notes = sweep_jobs(run_dir)
    opts = options.model_dump() if options is not None else {}
    for j in job_list:
        j.update(method=method, options=opts, split=split)
    workers = max(1, min(jobs or os.cpu_count() or 1, len(job_list)))
    if workers == 1:
        results = [_fit_point(j) for j in job_list]
    else:
        with ProcessPoolExecutor(max_workers=workers) as ex:
            results = list(ex.map(_fit_point, job_list))
    ok = [r for r in results if r["ok"]]
    gbear = None
    files = {}
    if ok:
        names = bearing_structure().names
        gbear = ReassembledBearing([(r["omega_rpm"], r["p_inj_bar"]) for r in ok],
                                   [[r["parameters"][n] for n in names] for r in ok],
                                   ok[0]["fs"], [r["fit_percent"] for r in ok])
        out = Path(out) if out else Path(run_dir) / "g_bear.yaml"
        gbear.save(out)
        files["model"] = str(out)
        files["report"] = str(_report(ok, out.parent / (out.stem + "_report")))
    return SweepResult(results, gbear, notes, files)


def _report(ok: list[dict], outdir: Path) -> Path:
    """Parameter tables and plots versus (Ω, P_I)."""
    from rigd.htmlreport import Report

    rep = Report(outdir, "Bearing parameters over the operating range")
    names = bearing_structure().names[:12]
    rows = sorted(ok, key=lambda r: (r["p_inj_bar"], r["omega_rpm"]))
    rep.table(["Ω rpm", "P_I bar", "fit %"] + names,
              [[f"{r['omega_rpm']:g}", f"{r['p_inj_bar']:g}", f"{r['fit_percent']:.1f}"]
               + [f"{r['parameters'][n]:.4g}" for n in names] for r in rows])
    pressures = sorted({r["p_inj_bar"] for r in ok})
    fig, ax = rep.figure("modes", "Natural frequencies and damping ratios versus Ω, one line "
                         "per injection pressure P_I", nrows=2, sharex=True)
    for p in pressures:
        rs = sorted([r for r in ok if r["p_inj_bar"] == p], key=lambda r: r["omega_rpm"])
        w = [r["omega_rpm"] for r in rs]
        for k in range(2):
            fn = [r["modes"][k]["f_n_hz"] if len(r["modes"]) > k and "f_n_hz" in r["modes"][k]
                  else np.nan for r in rs]
            z = [r["modes"][k]["zeta"] if len(r["modes"]) > k and "zeta" in r["modes"][k]
                 else np.nan for r in rs]
            ax[0].plot(w, fn, "o-", label=f"mode {k + 1}, P_I={p:g} bar")
            ax[1].plot(w, z, "o-")
    ax[0].set_ylabel("f_n (Hz)")
    ax[0].legend(fontsize=7)
    ax[1].set_ylabel("ζ (-)")
    ax[1].set_xlabel("Ω (rpm)")
    fig, ax = rep.figure("parameters", "Stiffness and damping parameters versus Ω",
                         nrows=2, sharex=True)
    for p in pressures:
        rs = sorted([r for r in ok if r["p_inj_bar"] == p], key=lambda r: r["omega_rpm"])
        w = [r["omega_rpm"] for r in rs]
        for n in ("k_xx", "k_yy", "k_xy", "k_yx"):
            ax[0].plot(w, [r["parameters"][n] for r in rs], "o-", label=f"{n} @{p:g} bar")
        for n in ("d_xx", "d_yy", "d_xy", "d_yx"):
            ax[1].plot(w, [r["parameters"][n] for r in rs], "o-", label=f"{n} @{p:g} bar")
    ax[0].legend(fontsize=6, ncol=2)
    ax[1].legend(fontsize=6, ncol=2)
    ax[1].set_xlabel("Ω (rpm)")
    return rep.write()
