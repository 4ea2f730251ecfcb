"""``python -m bench peers`` — rigd beside the black-box peers on the same splits (not in
``make bench``: ≈ 30–60 min; its output is one JSON object, not a figure artefact).

For each record — Silverbox (estimation 40600:, validation the arrow 0:40000, as the
docs/diagnose.md walk-through), the eight DaISy ``.mat`` records of ``../shared/data/daisy``
and the generated records of ``tests/gen`` (estimation the first 2/3, validation the last
1/3) — the held-out free-run fit (%, mean over outputs) and the wall time of:

* ``rigd``: ``rigd.api.identify`` (identify's base model, its validation fit) and
  ``rigd.api.diagnose`` (the first significant effect it names and its refitted fit);
* ``lti``: the general LTI base alone, :func:`rigd.ident.lti.order.choose_base` (its
  validation fit is the free run on from the estimation part's initial state, as rigd's);
* ``arx``: :func:`rigd.ident.lti.select_arx` (na = nb = n chosen on the estimation part);
* ``subspace``: :func:`rigd.ident.lti.select_subspace` (order chosen on the estimation part);
* ``narx``: SysIdentPy's FROLS polynomial NARX, one MISO model per output, degree and lags
  chosen on the estimation part (fitted on its first two thirds, scored by the free run on its
  last third; at most :data:`NARX_ROWS` samples, the latest, enter each fit), reported as
  ``diverged`` when its free run leaves the finite numbers or 10⁶ × the output's spread.

Validation outputs are never used: the peers' validation run starts from the state at the end
of the estimation part when the validation part follows it (:func:`rigd.ident.lti.heldout`),
else (Silverbox) from rest. ``RIGD_PEERS`` (comma-separated record names) restricts the
records; ``RIGD_PEERS_DIAGNOSE=0`` skips rigd's diagnosis, ``RIGD_PEERS_IDENTIFY=0`` rigd's
identify and diagnosis (the general LTI base column, :func:`_lti_base`, always runs). Each
record's row is also printed on stderr as it completes (``bench peers: row {...}``).
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = next((p / "shared" for p in ROOT.parents if (p / "shared" / "data").is_dir()),
              ROOT.parent / "shared")
#: largest number of samples one NARX fit sees (FROLS' cost grows with rows × candidates²)
NARX_ROWS = 6000
#: NARX (degree, lag) candidates; combinations over NARX_MAX_TERMS candidate terms skipped
NARX_GRID = [(1, 2), (1, 4), (2, 2), (2, 4), (3, 2)]
NARX_MAX_TERMS = 400

#: input hold of the general LTI base column (:func:`_lti_base`)
LTI_HOLD = "foh"

#: DaISy records: (time column or None, inputs, outputs, fs Hz when no usable time column)
DAISY = {"pHdata": (None, "2:3", "4", 0.1), "cstr": (None, "2", "3:4", 1 / 6.0),
         "dryer2": (None, "2:4", "5:7", 0.1), "evaporator": (None, "1:3", "4:6", 1.0),
         "glassfurnace": (None, "2:4", "5:10", 1.0), "steamgen": ("1", "2:5", "6:9", None),
         "winding": (None, "1:5", "6:7", 10.0), "thermic": (None, "1:2", "3", 1.0)}


def _records():
    """(name, Record, est slice, val slice) of every record: DaISy, Silverbox, generated."""
    from rigd.api.data import load
    from rigd.data.record import Record

    for name, (tcol, ins, outs, fs) in DAISY.items():
        path = SHARED / "data" / "daisy" / f"{name}.mat"
        if path.exists():
            rec = load(path, inputs=ins, outputs=outs, time_column=tcol,
                       fs=None if fs is None else repr(fs))
            cut = (2 * rec.n) // 3
            yield f"daisy/{name}", rec, slice(0, cut), slice(cut, rec.n)
    sb = SHARED / "data" / "silverbox" / "SNLS80mV.csv"
    if sb.exists():
        rec = load(sb, fs="610.3515625", inputs="V1", outputs="V2")
        yield "silverbox", rec, slice(40600, rec.n), slice(0, 40000)
    sys.path.insert(0, str(ROOT))
    from tests.gen import linear, nonlinear

    gens = {"gen/thermal_delay3": lambda: linear.thermal(delay=3, seed=1),
            "gen/integrator_pi": lambda: linear.integrator_loop(seed=1),
            "gen/hammerstein": lambda: nonlinear.hammerstein(seed=1),
            "gen/wiener": lambda: nonlinear.wiener(seed=1),
            "gen/structure_2in_3modes": lambda: linear.structure_2in_3modes(seed=1),
            "gen/structure_2in_6modes": lambda: linear.structure_2in_6modes(seed=1),
            "gen/bouc_wen": lambda: nonlinear.bouc_wen(seed=1)}
    for name, make in gens.items():
        g = make()
        head, data = g.columns()
        rec = Record({h: np.ascontiguousarray(data[:, i]) for i, h in enumerate(head)}, g.fs,
                     {"inputs": g.inputs, "outputs": g.outputs}, name)
        cut = (2 * rec.n) // 3
        yield name, rec, slice(0, cut), slice(cut, rec.n)


def _uy(rec):
    u = np.column_stack([rec.col(c) for c in rec.meta["inputs"]])
    y = np.column_stack([rec.col(c) for c in rec.meta["outputs"]])
    return u, y


def _timed(fn, *args):
    t0 = time.perf_counter()
    try:
        out = fn(*args)
    except Exception as exc:  # noqa: BLE001 - a peer failing is a result of the table
        out = {"status": f"failed: {type(exc).__name__}: {str(exc)[:120]}"}
    out["seconds"] = round(time.perf_counter() - t0, 2)
    return out


def _linear_peer(select, u, y, est, val):
    from rigd.ident.figures import fit_percent
    from rigd.ident.lti import heldout

    model, order = select(u[est], y[est])
    if val.start == est.stop:
        fit = heldout(model, u[est.start:val.stop], y[est.start:val.stop],
                      est.stop - est.start)[0]
    else:   # validation before the estimation part (Silverbox): from rest
        with np.errstate(all="ignore"):
            yhat = model.simulate(u[val], np.zeros(model.order))
        fit = fit_percent(y[val], yhat)
    fit = float(np.mean(fit))
    ok = np.isfinite(fit) and fit > -1e3
    return {"fit_percent": round(fit, 2) if ok else None, "order": order,
            "status": "ok" if ok else "diverged"}


def _arx(u, y):
    from rigd.ident.lti import select_arx

    s = select_arx(u, y, orders=(1, 2, 3, 4, 5, 6, 8, 10, 15, 20, 30))
    return s.model.to_linear(), s.order


def _subspace(u, y):
    from rigd.ident.lti import select_subspace

    r, _ = select_subspace(u, y, orders=(1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20))
    return r.model, r.order


def _narx_sim(model, u, y_init, lag, n):
    """Free run of a FROLS model over u (n + lag rows) from the lag outputs y_init."""
    with np.errstate(all="ignore"):
        yh = model.predict(X=u, y=np.vstack([y_init, np.zeros((n, 1))]))
    return np.asarray(yh, float).reshape(-1)[lag:lag + n]


def _narx_fit(u, y, degree, lag):
    from sysidentpy.basis_function import Polynomial
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.parameter_estimation import LeastSquares

    m = FROLS(order_selection=True, n_info_values=15, ylag=lag, xlag=[list(range(1, lag + 1))]
              * u.shape[1] if u.shape[1] > 1 else lag, info_criteria="aic",
              estimator=LeastSquares(), basis_function=Polynomial(degree=degree))
    m.fit(X=u[-NARX_ROWS:], y=y[-NARX_ROWS:, None])
    return m


def _narx_output(u, y, est, val):
    """Held-out free-run prediction of one output y (n,) by the FROLS NARX chosen on est."""
    from math import comb

    from rigd.ident.figures import fit_percent

    ue, ye = u[est], y[est]
    cut = (2 * len(ue)) // 3
    best, best_fit = None, -np.inf
    for degree, lag in NARX_GRID:
        if comb(lag * (1 + u.shape[1]) + degree, degree) > NARX_MAX_TERMS:
            continue
        try:
            m = _narx_fit(ue[:cut], ye[:cut], degree, lag)
            yh = _narx_sim(m, ue[cut - lag:], ye[cut - lag:cut, None], lag, len(ue) - cut)
        except Exception:  # noqa: BLE001 - a setting FROLS cannot fit is skipped
            continue
        f = float(fit_percent(ye[cut:], yh)[0]) if np.all(np.isfinite(yh)) else -np.inf
        if f > best_fit:
            best, best_fit = (degree, lag), f
    if best is None:
        raise ValueError("no NARX setting could be fitted")
    degree, lag = best
    m = _narx_fit(ue, ye, degree, lag)
    if val.start == est.stop:
        yh = _narx_sim(m, u[est.stop - lag:val.stop], ye[-lag:, None], lag, val.stop - val.start)
    else:
        uu = np.vstack([np.zeros((lag, u.shape[1])), u[val]])
        yh = _narx_sim(m, uu, np.zeros((lag, 1)), lag, val.stop - val.start)
    return yh, f"degree {degree}, lags {lag}"


def _narx(u, y, est, val):
    from rigd.ident.figures import fit_percent

    u0, y0 = u[est].mean(0), y[est].mean(0)
    du, dy = u - u0, y - y0
    fits, settings, diverged = [], [], False
    for i in range(y.shape[1]):
        yh, setting = _narx_output(du, dy[:, i], est, val)
        settings.append(setting)
        if not np.all(np.isfinite(yh)) or np.max(np.abs(yh)) > 1e6 * np.std(dy[est, i]):
            diverged = True
            continue
        fits.append(float(fit_percent(dy[val, i], yh)[0]))
    if diverged:
        return {"fit_percent": None, "status": "diverged", "settings": settings}
    return {"fit_percent": round(float(np.mean(fits)), 2), "status": "ok",
            "settings": settings}


def _rigd(rec, est, val, diagnose: bool):
    from rigd import api

    es, vs = f"{est.start}:{est.stop}", f"{val.start}:{val.stop}"
    ident = api.identify(rec, est=es, val=vs)
    out = {"fit_percent": round(float(np.mean(np.atleast_1d(ident.fit_percent))), 2),
           "status": "ok"}
    if diagnose:
        d = api.diagnose(rec, est=es, val=vs).summary()
        top = next((f for f in d.get("findings", []) if f.get("significant")), None)
        out["diagnose_base"] = d.get("fit_percent")
        if top:
            out["effect"] = top["effect"]
            out["fit_percent_with_effect"] = round(float(top["fit_percent_with"]), 2)
    return out


def _lti_base(rec, u, y, est, val):
    """The general LTI base alone (:func:`rigd.ident.lti.order.choose_base`, hold
    :data:`LTI_HOLD`, no mechanical model competing): its held-out fit, family, states and
    delays, and the CPU seconds it took (the machine is shared: wall time says little)."""
    from rigd.ident.figures import fit_percent
    from rigd.ident.iddata import IdData
    from rigd.ident.lti.order import choose_base

    d = IdData(u, y, float(rec.fs), list(rec.meta["inputs"]), list(rec.meta["outputs"]))
    t0 = time.process_time()
    c = choose_base(d, est, val, hold=LTI_HOLD)
    cpu = time.process_time() - t0
    with np.errstate(all="ignore"):
        fit = float(np.mean(fit_percent(y[val], c.structure.simulate(c.theta, d)[val])))
    ok = np.isfinite(fit) and fit > -1e3
    return {"fit_percent": round(fit, 2) if ok else None, "status": "ok" if ok else "diverged",
            "family": c.family, "states": int(c.states), "delays": list(c.delays),
            "cpu_s": round(cpu, 1)}


def run() -> dict:
    """The peers table (module docstring): ``{"peers": {record: {tool: {...}}}}``."""
    wanted = [s for s in os.environ.get("RIGD_PEERS", "").split(",") if s]
    diagnose = os.environ.get("RIGD_PEERS_DIAGNOSE", "1") != "0"
    identify = os.environ.get("RIGD_PEERS_IDENTIFY", "1") != "0"
    try:
        import sysidentpy  # noqa: F401
        have_narx = True
    except ImportError:
        have_narx = False
    table: dict = {}
    for name, rec, est, val in _records():
        if wanted and not any(w in name for w in wanted):
            continue
        print(f"bench peers: {name} ({rec.n} samples)", file=sys.stderr, flush=True)
        u, y = _uy(rec)
        row = {"n": int(rec.n), "inputs": u.shape[1], "outputs": y.shape[1],
               "est": [est.start, est.stop], "val": [val.start, val.stop]}
        row["rigd"] = (_timed(_rigd, rec, est, val, diagnose) if identify else
                       {"status": "not run"})
        row["lti"] = _timed(_lti_base, rec, u, y, est, val)
        row["arx"] = _timed(_linear_peer, _arx, u, y, est, val)
        row["subspace"] = _timed(_linear_peer, _subspace, u, y, est, val)
        row["narx"] = (_timed(_narx, u, y, est, val) if have_narx else
                       {"status": "sysidentpy not installed (make peers-deps)"})
        table[name] = row
        print(f"bench peers: row {json.dumps({name: row})}", file=sys.stderr, flush=True)
    return {"peers": table}


def margin(row: dict) -> float | None:
    """rigd's base held-out fit minus the better of the ARX and subspace models' (points;
    issue 20's Must-show: >= -1), None when either side has no figure."""
    base = row["rigd"].get("fit_percent")
    refs = [row[k]["fit_percent"] for k in ("arx", "subspace")
            if row.get(k, {}).get("fit_percent") is not None]
    return None if base is None or not refs else round(base - max(refs), 2)


def markdown(table: dict) -> str:
    """The table of docs/diagnose.md from :func:`run`'s ``peers`` object."""
    def cell(r, key="fit_percent"):
        if r.get(key) is None:
            return r.get("status", "–").split(":")[0]
        return f"{r[key]:.2f} ({r['seconds']:.0f} s)"

    def lti(r):
        if r is None:
            return "not run"
        if r.get("fit_percent") is None:
            return r.get("status", "–").split(":")[0]
        return (f"{r['fit_percent']:.2f} ({r['cpu_s']:.0f} s CPU) {r['family']} "
                f"{r['states']} st., delays {r['delays']}")

    def base(r):
        out = cell(r)
        d = r.get("diagnose_base")
        if d is not None and r.get("fit_percent") is not None and \
                abs(d - r["fit_percent"]) >= 0.01:
            out += f"; diagnosed on another base: {d:.2f}"
        return out

    lines = ["| record (n, in×out) | rigd base | rigd + effect | LTI base (choose_base) | "
             "ARX (n) | subspace (order) | NARX FROLS | base − best of ARX, subspace |",
             "|---|---|---|---|---|---|---|---|"]
    for name, row in table.items():
        r = row["rigd"]
        eff = (f"{r['fit_percent_with_effect']:.2f} ({r['effect']})" if r.get("effect")
               else "none named" if "diagnose_base" in r else "not run")
        m = margin(row)
        lines.append(
            f"| {name} ({row['n']}, {row['inputs']}×{row['outputs']}) | {base(r)} | {eff} | "
            f"{lti(row.get('lti'))} | "
            f"{cell(row['arx'])} n={row['arx'].get('order', '–')} | {cell(row['subspace'])} "
            f"n={row['subspace'].get('order', '–')} | {cell(row['narx'])} | "
            f"{'–' if m is None else f'{m:+.2f}'} |")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    res = run()
    print(json.dumps(res, indent=2))
    print(markdown(res["peers"]), file=sys.stderr)
