"""``rigd web``: the rig in a browser (docs/web.md).

A separate process and a client of the daemon's control socket: the loop's real-time process
never serves a browser. Modules, one job each:

* :mod:`rigd.web.app` — the Starlette application and its routes;
* :mod:`rigd.web.auth` — the control and read-only tokens (files, generation, check) and the
  read-only session cookie of ``POST /api/login``;
* :mod:`rigd.web.guard` — the ASGI guard before any route: Host check, head/target/body
  limits, token or session, body time limit;
* :mod:`rigd.web.conn` — uvicorn's h11 protocol with a request-head timeout and a connection
  cap sized from the descriptor limit (slow clients);
* :mod:`rigd.web.files` — files of the runs folder served by type, uploads kept as data,
  listings that never follow a symlink;
* :mod:`rigd.web.ctl` — the bridge to the daemon socket (:mod:`rigd.service.client`);
* :mod:`rigd.web.sse` — ``GET /api/stream``: the daemon's ``stream.subscribe`` as Server-Sent
  Events;
* :mod:`rigd.web.paths` — every file path from a request, checked to stay inside the runs and
  config folders;
* :mod:`rigd.web.runs` — the runs folder (manifests) and server-side min/max decimation of
  records;
* ``static/`` — the console page (``index.html``, ``app.js``, ``style.css``); Plotly's JS comes
  from the installed plotly wheel, nothing from a CDN.
"""
