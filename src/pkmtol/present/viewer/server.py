"""A loopback-only meshcat server subprocess (:mod:`pkmtol.present.viewer.meshcat_server`) and its client."""

from __future__ import annotations

import atexit
import contextlib
import io
import os
import select
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from pkmtol.exceptions import ViewerError
from pkmtol.present.viewer.backend import require_meshcat


class MeshcatServer:
    """A loopback-only meshcat server subprocess (:mod:`pkmtol.meshcat_server`) and a client.

    Use as a context manager, or call :meth:`close`; the server is also stopped at interpreter
    exit, and exits by itself when this process dies.

    Attributes:
        proc: The server process (``subprocess.Popen``).
        zmq_url: Its ZeroMQ address (``tcp://127.0.0.1:…``).
        web_url: The viewer's address (``http://127.0.0.1:…/static/``).

    """

    def __init__(self, timeout_s: float = 30.0) -> None:
        require_meshcat()
        cmd = [sys.executable, "-u", "-m", "pkmtol.present.viewer.meshcat_server"]
        cmd += ["--parent-pid", str(os.getpid())]
        env = dict(os.environ)
        src = str(Path(__file__).resolve().parents[3])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (env.get("PYTHONPATH"), src) if p)
        try:
            self.proc = subprocess.Popen(
                cmd,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                env=env,
                start_new_session=True,
            )
        except OSError as err:
            raise ViewerError(f"cannot start the meshcat server ({err})") from err
        self._vis: Any = None
        self._closed = False
        atexit.register(self.close)
        try:
            urls = self._read_urls(timeout_s)
        except BaseException:
            self.close()
            raise
        self.zmq_url, self.web_url = urls["zmq_url"], urls["web_url"]

    def _read_urls(self, timeout_s: float) -> dict[str, str]:
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        deadline = time.monotonic() + timeout_s
        buf = b""
        while buf.count(b"\n") < 2:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ViewerError(f"the meshcat server did not start within {timeout_s:g} s")
            ready, _, _ = select.select([fd], [], [], remaining)
            if ready:
                chunk = os.read(fd, 4096)
                if not chunk:
                    raise ViewerError(
                        f"the meshcat server exited at start (code {self.proc.wait()}); "
                        f"run `{sys.executable} -m pkmtol.present.viewer.meshcat_server` to see why"
                    )
                buf += chunk
        out = {}
        for line in buf.decode("utf-8").splitlines()[:2]:
            key, _, value = line.partition("=")
            out[key.strip()] = value.strip()
        if set(out) != {"zmq_url", "web_url"}:
            raise ViewerError(f"unexpected output from the meshcat server: {buf!r}")
        return out

    @property
    def pid(self) -> int:
        """Process id of the server."""
        return int(self.proc.pid)

    @property
    def visualizer(self) -> Any:
        """A ``meshcat.Visualizer`` connected to this server."""
        if self._closed:
            raise ViewerError("the meshcat server has been stopped")
        if self._vis is None:
            import zmq

            meshcat = require_meshcat()
            with contextlib.redirect_stdout(io.StringIO()):  # it prints the URL
                self._vis = meshcat.Visualizer(zmq_url=self.zmq_url)
            sock = self._vis.window.zmq_socket
            sock.setsockopt(zmq.LINGER, 0)
            sock.setsockopt(zmq.RCVTIMEO, 120_000)
        return self._vis

    def close(self) -> None:
        """Stop the server (terminate, then kill after 5 s) and reap it. Idempotent."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(Exception):
            atexit.unregister(self.close)
        if self._vis is not None:
            with contextlib.suppress(Exception):
                self._vis.window.zmq_socket.close(linger=0)
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()

    def __enter__(self) -> MeshcatServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
