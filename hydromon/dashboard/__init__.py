"""The web dashboard of the fleet (``hydromon dashboard``) and the Foxglove bridge.

* :mod:`hydromon.dashboard.fleet`: what the dashboard knows (rows, flags, history, events), no I/O;
* :mod:`hydromon.dashboard.bus`: the bus side (subscriptions, liveliness, queries), read-only;
* :mod:`hydromon.dashboard.app`: the Starlette app (pages, push WebSocket, security headers);
* :mod:`hydromon.dashboard.server`, :mod:`hydromon.dashboard.service`: uvicorn, and the pieces wired
  for the bus or a recording;
* ``static/``: the pages, their scripts and styles, and uPlot (vendored, see ``static/vendor/uplot/VERSION``).
"""
