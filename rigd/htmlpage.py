"""Self-contained interactive HTML pages: plotly.min.js, the page's data and its script inlined.

``rigd compare --report`` and ``rigd diagnose --report`` write ``DIR/index.html`` with this
module; the page works from a ``file://`` URL with no internet and no server, and unchanged
when ``rigd web`` serves the folder over HTTP (it refers to nothing but the PNGs beside it, by
relative name). The page is three inlined parts:

* plotly.min.js from the installed plotly wheel (``plotly/package_data/plotly.min.js``; the
  package itself is not imported);
* the page data, one JSON object (``<script type="application/json" id="page-data">``), strict
  JSON: NaN and ±inf become ``null`` (:func:`json_safe`), ``<`` is escaped so no string can
  close the script element;
* the page script and style (``rigd/page_assets/report.js``, ``report.css``), which draw the
  data with Plotly.

What the data holds is built by the page modules (``rigd.diagnose.page_data`` and the compare
and diagnose pages); :func:`minmax_decimate` keeps long records small.
"""

from __future__ import annotations

import html
import importlib.util
import json
import math
import os
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from rigd.errors import InputError
from rigd.fileio import atomic_write_text

ASSETS = Path(__file__).with_name("page_assets")


@lru_cache(maxsize=1)
def plotly_js() -> str:
    """The text of plotly.min.js shipped in the installed plotly wheel.

    Raises
    ------
    InputError
        plotly is not installed (the interactive pages need it; ``pip install plotly``).
    """
    spec = importlib.util.find_spec("plotly")
    locs = list(spec.submodule_search_locations or []) if spec else []
    for loc in locs:
        path = Path(loc) / "package_data" / "plotly.min.js"
        if path.is_file():
            return path.read_text(encoding="utf-8")
    raise InputError("plotly.min.js not found: the interactive report needs the plotly "
                     "package (pip install plotly)", "--report")


def json_safe(obj: Any, digits: int = 6) -> Any:
    """``obj`` as plain JSON values: numpy arrays/scalars to lists/numbers, NaN/±inf to None.

    Floats are rounded to ``digits`` significant digits (the page shows curves, not
    archives; this keeps a page of a long record small).
    """
    if isinstance(obj, dict):
        return {str(k): json_safe(v, digits) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v, digits) for v in obj]
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fc":
            a = np.asarray(obj, float)
            out = np.vectorize(lambda v: float(f"{v:.{digits}g}"), otypes=[object])(a) \
                if a.size else a.astype(object)
            out[~np.isfinite(a)] = None
            return out.tolist()
        return json_safe(obj.tolist(), digits)
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return float(f"{v:.{digits}g}") if math.isfinite(v) else None
    if obj is None or isinstance(obj, str):
        return obj
    return str(obj)  # anything else (a path, an enum) as its text


def minmax_decimate(x: np.ndarray, y: np.ndarray, points: int = 2000
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Min/max decimation of one trace to at most ``points`` points.

    The samples are cut into ``points // 2`` consecutive buckets; each bucket keeps its
    smallest and its largest sample, in time order, so every peak of the record stays on the
    plot (a plain subsample would drop them). Records of at most ``points`` samples are
    returned whole.

    Parameters
    ----------
    x, y : ndarray (n,)
        Abscissa (e.g. time, s) and values.
    points : int
        Most points returned (≥ 2).

    Returns
    -------
    (x, y) : ndarray
        The kept samples, in order.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    n = y.shape[0]
    if n <= points:
        return x, y
    nb = max(1, points // 2)
    edges = np.linspace(0, n, nb + 1).astype(int)
    keep = []
    for a, b in zip(edges[:-1], edges[1:]):
        seg = y[a:b]
        i, j = a + int(np.nanargmin(seg)), a + int(np.nanargmax(seg))
        keep += [min(i, j), max(i, j)] if i != j else [i]
    idx = np.asarray(keep)
    return x[idx], y[idx]


def report_dir(out: str | Path, what: str = "--report") -> Path:
    """Create the report folder ``out`` (with its parents) or say in one line why not.

    Called before the work a report describes, so a bad ``--report`` costs no diagnosis.

    Raises
    ------
    InputError
        ``out`` is a file, or cannot be created or written.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out} is a file, not a folder for the report", what)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the report folder {out}: {exc.strerror}",
                         what) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"the report folder {out} is not writable", what)
    return out


def page_json(data: dict[str, Any]) -> str:
    """The page data as strict JSON safe to inline in a ``<script>`` element."""
    text = json.dumps(json_safe(data), allow_nan=False, separators=(",", ":"))
    return text.replace("<", "\\u003c")


def write_page(out: str | Path, title: str, data: dict[str, Any],
               name: str = "index.html") -> Path:
    """Write the interactive page ``out/name`` atomically (caller's umask); return its path.

    ``data`` is the page data (``kind`` ``"compare"`` or ``"diagnose"``, see the page
    modules); the script ``page_assets/report.js`` draws it.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    js = (ASSETS / "report.js").read_text(encoding="utf-8")
    css = (ASSETS / "report.css").read_text(encoding="utf-8")
    plotly = plotly_js().replace("</script", "<\\/script")
    page = ("<!doctype html>\n<html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width,initial-scale=1'>"
            "<link rel='icon' href='data:,'>"  # no favicon request (a 404 over HTTP)
            f"<title>{html.escape(title)}</title><style>{css}</style>\n"
            # plotly's bundle has no '</script'; guard anyway so a future one cannot end
            # the element early
            f"<script>{plotly}</script></head>\n"
            f"<body><h1>{html.escape(title)}</h1><div id='app'></div>\n"
            f"<script type='application/json' id='page-data'>{page_json(data)}</script>\n"
            f"<script>{js}</script></body></html>\n")
    path = out / name
    atomic_write_text(path, page)
    return path
