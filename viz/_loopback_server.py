"""meshcat's ZMQ/websocket server, bound to 127.0.0.1 only (run as ``python -m viz._loopback_server``).

meshcat 0.3.2's server binds its ZMQ socket to 127.0.0.1 but its web server to every
interface. This entry point reuses meshcat's bridge and only changes where the web server
listens, and serves its own index page (meshcat's, plus a ``#target=x,y,z`` fragment that aims
the camera's orbit target). It prints ``zmq_url=...`` and ``web_url=...`` on stdout (the parent
reads them) and exits when its parent closes its standard input or sends SIGTERM.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import warnings
from pathlib import Path

HOST = "127.0.0.1"


def main(argv: list[str] | None = None) -> int:
    """Start the bridge and serve until stdin closes or SIGTERM."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--port", type=int, default=None, help="web port (default: first free from 7000)")
    parser.add_argument("--zmq-port", type=int, default=None, help="ZMQ port (default: first free from 6000)")
    args = parser.parse_args(argv)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import tornado.ioloop
        import tornado.web
        from meshcat.servers import zmqserver

    class LoopbackApplication(tornado.web.Application):
        def listen(self, port, address=None, **kwargs):  # noqa: ARG002 - always loopback
            return super().listen(port, address=HOST, **kwargs)

    index = (Path(__file__).with_name("live_index.html")).read_bytes()

    class IndexHandler(tornado.web.RequestHandler):
        def get(self) -> None:
            self.set_header("Content-Type", "text/html; charset=utf-8")
            self.set_header("Cache-Control", "no-store")
            self.write(index)

    class LoopbackBridge(zmqserver.ZMQWebSocketBridge):
        def make_app(self):
            # meshcat's two routes (static files, websocket) plus our index page, loopback only
            return LoopbackApplication([
                (r"/static/", IndexHandler),
                (r"/static/(.*)", zmqserver.StaticFileHandlerNoCache,
                 {"path": zmqserver.VIEWER_ROOT, "default_filename": zmqserver.VIEWER_HTML}),
                (r"/", zmqserver.WebSocketHandler, {"bridge": self}),
            ])

    zmq_url = f"tcp://{HOST}:{args.zmq_port}" if args.zmq_port else None
    bridge = LoopbackBridge(zmq_url=zmq_url, host=HOST, port=args.port)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)

    loop = tornado.ioloop.IOLoop.current()

    for sig in (signal.SIGTERM, signal.SIGINT):
        # tornado 6: IOLoop.current() is a BaseAsyncIOLoop, which the IOLoop annotation does not say
        loop.asyncio_loop.add_signal_handler(sig, loop.stop)  # type: ignore[attr-defined]

    def watch_parent() -> None:
        # the parent holds our stdin open; EOF means it is gone (even after SIGKILL)
        try:
            sys.stdin.buffer.read()
        except (OSError, ValueError):
            pass
        loop.add_callback(loop.stop)

    threading.Thread(target=watch_parent, daemon=True).start()
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
