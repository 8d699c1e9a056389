"""A scripted local HTTP server for the tests of the chat-server clients (the LLM spatial parser,
the chat planner)."""

from __future__ import annotations

import contextlib
import threading
from http.server import ThreadingHTTPServer


@contextlib.contextmanager
def scripted_server(handler, stop: threading.Event):
    """A local HTTP server answering with ``handler`` (a request handler class) on a free port, in a
    thread; yields its ``/v1`` base URL. On exit ``stop`` is set (a slow reply waits on it) and the
    server shut down."""
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    httpd.daemon_threads = True
    thread = threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.02}, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}/v1"
    finally:
        stop.set()
        httpd.shutdown()
        httpd.server_close()
        thread.join()
