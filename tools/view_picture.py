"""A picture of a rerun recording as rerun's web viewer shows it (docs/view.md's figure).

Usage: python tools/view_picture.py RECORDING.rrd OUT.png [--size 1400x900] [--wait-s 40]

Serves the recording with rerun's own web viewer (``rerun --serve-web``, from the rerun-sdk
package, on loopback ports) and takes a screenshot with headless Chromium (Debian's ``chromium``:
``apt-get install chromium``; its software WebGL, SwiftShader, draws the viewer), then stops the
server. Nothing leaves the machine: the viewer and the recording are served from 127.0.0.1.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.parse
import urllib.request
from pathlib import Path


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recording", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--size", default="1400x900", help="window size, WIDTHxHEIGHT")
    ap.add_argument("--wait-s", type=float, default=40.0, help="how long the page may load and draw (virtual time, s)")
    ap.add_argument("--web-port", type=int, default=9090, help="the viewer's port: Chromium keeps the viewer's compiled code per address, so a fixed one draws sooner on later runs")
    ap.add_argument("--tries", type=int, default=4, help="screenshots to try until the viewer has drawn")
    a = ap.parse_args(argv)
    rerun = Path(sys.executable).parent / "rerun"
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if not rerun.exists():
        raise SystemExit(f"{rerun} not found: pip install 'solid-lidar[viewer]'")
    if chromium is None:
        raise SystemExit("chromium not found: apt-get install chromium")
    web, grpc = a.web_port, free_port()
    env = dict(os.environ, RERUN_ANALYTICS="0")  # nothing to send, and nowhere to send it
    server = subprocess.Popen(
        [str(rerun), "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(web), "--port", str(grpc), str(a.recording)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=2).close()
                break
            except OSError:
                if time.monotonic() > deadline or server.poll() is not None:
                    raise SystemExit("rerun's web viewer did not start") from None
                time.sleep(0.5)
        time.sleep(5.0)  # the recording loads into the viewer's server
        source = urllib.parse.quote(f"rerun+http://127.0.0.1:{grpc}/proxy", safe="")
        w, h = a.size.split("x")
        cmd = [
            chromium, "--headless=new", "--no-sandbox", "--disable-gpu-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
            "--ignore-gpu-blocklist", f"--window-size={w},{h}", f"--virtual-time-budget={int(a.wait_s * 1000)}",
            f"--screenshot={a.out.resolve()}", f"http://127.0.0.1:{web}/?url={source}",
        ]  # fmt: skip
        # The viewer compiles its WebAssembly in real time while the page's clock is virtual: a
        # screenshot taken before the viewer drew is the bare loading page (a few kB). Try again.
        for attempt in range(a.tries):
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=300)
            if a.out.stat().st_size > 50_000:
                break
            print(f"attempt {attempt + 1}: the viewer had not drawn yet", file=sys.stderr)
        else:
            raise SystemExit(f"the viewer drew nothing in {a.tries} attempts: {a.out} shows the loading page")
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=30)
    print(f"wrote {a.out} ({a.out.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
