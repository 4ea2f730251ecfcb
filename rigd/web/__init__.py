"""``rigd web``: the rig in a browser (docs/web.md).

A separate process and a client of the daemon's control socket: the loop's real-time process
never serves a browser. Modules, one job each:

* :mod:`rigd.web.app` — the Starlette application and its routes;
* :mod:`rigd.web.auth` — the Bearer token (file, generation, check) and the request guards
  (token on state-changing requests, body size limit);
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
