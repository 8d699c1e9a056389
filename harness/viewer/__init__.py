"""``cfharness view MAP.npz``: a fused map in the browser, with text, click and image queries.

* :mod:`harness.viewer.queries` - a map file opened with the agents' mapper: text, click and image
  queries answered as JSON-ready dicts (regions, per-point heat, "not found" with its reason);
* :mod:`harness.viewer.server` - the loopback-only web server: the page, the points, the query
  endpoints, files of the map's folder and nothing outside it;
* ``static/`` - the page (``index.html``, ``viewer.js``) and three.js, vendored from the npm
  registry at a pinned version (:data:`THREE_VERSION`, ``static/vendor/README.md``), so the page
  works offline.

May import: :mod:`agents` (the mapper), :mod:`conceptfusion`, :mod:`harness.report.paths` (replay names).
"""

__all__ = ["THREE_VERSION"]

THREE_VERSION = "0.170.0"
"""The vendored three.js release (``static/vendor/three.module.min.js``)."""
