"""A meshcat server that listens on the loopback interface only (run as a subprocess).

meshcat 0.3's own server (``meshcat.Visualizer()`` / ``meshcat-server``) binds its ZeroMQ socket to
127.0.0.1 but its HTTP/WebSocket file server to every interface (``0.0.0.0`` and ``::``), which
would publish the scene to the network. This module runs the same bridge with the HTTP server
bound to 127.0.0.1, and exits by itself when the process that started it is gone (no orphans
even if that process is killed). :class:`pkmtol.present.viewer.server.MeshcatServer` starts and stops it.

Usage: ``python -m pkmtol.present.viewer.meshcat_server [--parent-pid PID]``; prints ``zmq_url=…`` and
``web_url=…`` on the first two lines of stdout.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

import tornado.ioloop
import tornado.web
from meshcat.servers import zmqserver

#: The only address the servers listen on.
HOST = "127.0.0.1"


class _LoopbackApplication(tornado.web.Application):
    """A tornado application whose ``listen`` binds the loopback interface only."""

    def listen(self, port: int, address: str | None = None, **kwargs: Any) -> Any:  # noqa: D102
        return super().listen(port, address=HOST, **kwargs)


class LoopbackBridge(zmqserver.ZMQWebSocketBridge):
    """meshcat's ZMQ ↔ WebSocket bridge with every socket on 127.0.0.1."""

    def __init__(self) -> None:
        super().__init__(zmq_url=None, host=HOST)

    def make_app(self) -> tornado.web.Application:
        """Build the same routes as meshcat's bridge, in a loopback-only application."""
        return _LoopbackApplication(
            [
                (
                    r"/static/(.*)",
                    zmqserver.StaticFileHandlerNoCache,
                    {"path": zmqserver.VIEWER_ROOT, "default_filename": zmqserver.VIEWER_HTML},
                ),
                (r"/", zmqserver.WebSocketHandler, {"bridge": self}),
            ]
        )


def main(argv: list[str] | None = None) -> None:
    """Run the loopback bridge until killed or until the parent process exits."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parent-pid", type=int, default=None)
    args = parser.parse_args(argv)
    bridge = LoopbackBridge()
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    # nobody reads our output after the two lines: send it nowhere so a full pipe cannot block us
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    sys.stdout = sys.stderr = open(os.devnull, "w")  # noqa: SIM115 - lives as long as the process

    if args.parent_pid is not None:
        parent = args.parent_pid

        def check_parent() -> None:
            if os.getppid() != parent:
                tornado.ioloop.IOLoop.current().stop()

        tornado.ioloop.PeriodicCallback(check_parent, 500).start()
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main()
