"""The rendered report in a real browser: headless Chromium loads it without errors or requests.

Chromium is driven through the DevTools protocol on a pipe (``--remote-debugging-pipe``: JSON
messages separated by NUL bytes, written to its fd 3 and read from its fd 4), so no port, no
extra package and no change to the report is needed. Skips when ``/usr/bin/chromium`` (Debian
package ``chromium``) is absent.
"""

from __future__ import annotations

import fcntl
import json
import os
import select
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

from imucal import ImuCalibration, SensorCalibration
from imucal.report import build_report_context, render_report

CHROMIUM = Path("/usr/bin/chromium")
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--remote-debugging-pipe",
)
TIMEOUT_S = 60.0

pytestmark = pytest.mark.skipif(
    not os.access(CHROMIUM, os.X_OK),
    reason=f"{CHROMIUM} not found (Debian package 'chromium'); browser check skipped",
)


class DevTools:
    """Minimal client of the DevTools protocol over Chromium's pipe."""

    def __init__(self, user_data_dir: Path) -> None:
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()

        def pipe_fds() -> None:
            # Chromium reads commands from its fd 3 and writes replies and events to its fd 4.
            # Copies above 10 first so that neither dup2 overwrites the other pipe end.
            r = fcntl.fcntl(to_browser_r, fcntl.F_DUPFD, 10)
            w = fcntl.fcntl(from_browser_w, fcntl.F_DUPFD, 10)
            os.dup2(r, 3)
            os.dup2(w, 4)

        # close_fds=False keeps the inheritable fds 3 and 4 that pipe_fds makes; every other fd
        # Python opens is non-inheritable (PEP 446) and is not passed on.
        self.proc = subprocess.Popen(
            [str(CHROMIUM), *FLAGS, f"--user-data-dir={user_data_dir}", "about:blank"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            close_fds=False,
            preexec_fn=pipe_fds,  # noqa: PLW1509 (the test starts no thread)
        )
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._buffer = b""
        self._next_id = 0
        self.events: list[dict] = []
        self.deadline = time.monotonic() + TIMEOUT_S

    def close(self) -> None:
        try:
            self.send("Browser.close", wait=False)
        except OSError:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._to_browser)
        os.close(self._from_browser)

    def _read_message(self) -> dict:
        while b"\0" not in self._buffer:
            left = self.deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no answer from Chromium within {TIMEOUT_S} s")
            ready, _, _ = select.select([self._from_browser], [], [], left)
            if ready:
                chunk = os.read(self._from_browser, 1 << 16)
                if not chunk:
                    raise RuntimeError(f"Chromium closed the pipe (exit {self.proc.poll()})")
                self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(message)

    def send(
        self, method: str, params: dict | None = None, session: str | None = None, wait: bool = True
    ) -> dict:
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if session is not None:
            message["sessionId"] = session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        while wait:
            reply = self._read_message()
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]
            self.events.append(reply)
        return {}

    def wait_for(self, method: str, session: str) -> dict:
        for event in self.events:
            if event.get("method") == method and event.get("sessionId") == session:
                return event
        while True:
            event = self._read_message()
            self.events.append(event)
            if event.get("method") == method and event.get("sessionId") == session:
                return event


def _figure(path: Path, width_in: float) -> Path:
    fig = Figure(figsize=(width_in, 2.0))
    fig.subplots().plot(np.arange(5) ** 2)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=50)
    return path


def _consistency() -> dict:
    """A check of the standard deviations with every column filled and a long reason."""
    groups = {
        g: {"rms_z": 10.4, "rank": 3, "p_value": 1e-70}
        for g in ("bias", "matrix", "scale", "xi_rad", "alpha_rad", "all")
    }
    checked = {
        "stage": "mag_step1",
        "parts": {"scheme": "halves", "groups": groups, "max_abs_z": 10.3,
                  "max_parameter": "xi_y_rad", "heldout": {"ratio": 0.041}},
        "leave_one_out": {"rms_z": 1.19, "n": 53, "basis": "poses"},
        "inflation": {"bias": 10.4, "matrix": 6.03},
        "warnings": ["mag_step1: its bias differs between two independent parts"],
    }  # fmt: skip
    reason = "halves: part 1 shipped gyr_bias; part 2 shipped gyr_bias; within: both parts "
    unchecked = {
        "stage": "gyr_known_rotation",
        "reason": reason * 3,
        "inflation": {"bias": 1.0, "matrix": 1.0},
        "warnings": [f"gyr_known_rotation: not checked ({reason})"],
    }
    return {
        "sensors": {"mag": checked, "gyr": unchecked},
        "limit_rms_z": 1.5,
        "heldout_ratio": 0.5,
    }


def test_report_loads_in_chromium_without_errors(tmp_path):
    eye = np.eye(3).tolist()
    calibration = ImuCalibration(
        *(
            SensorCalibration(s, [0.1, 0.2, 0.3], eye, u, method="test")
            for s, u in (("acc", "m/s^2"), ("gyr", "rad/s"), ("mag", "normalised"))
        )
    ).to_dict()
    summary = {
        "dataset": "demo",
        "lost_packets": 2,
        "recordings": {
            "rotation3d": {
                "source": "raw/rotation3d.csv",
                "sha256": "ab" * 32,
                "rows": 100,
                "duration_s": 1.0,
                "rate_hz": 100.0,
                "lost_packets": 2,
                "n_gaps": 1,
                "gaps": [
                    {"line": 50, "t_s": 0.5, "dt_s": 0.03, "seq_before": 47, "seq": 50, "lost": 2}
                ],
            },
        },
    }
    figures = [
        _figure(tmp_path / "segments" / "rotation3d.png", 4),
        _figure(tmp_path / "figures" / "mag_raw.png", 3),
        _figure(tmp_path / "figures" / "validation.png", 5),
    ]
    context = build_report_context(
        dataset="demo",
        summary=summary,
        calibration=calibration,
        mag_result={
            "warnings": ["a warning"],
            "rms": 0.01,
            # the designed tables and the collapsed listing of every field, with long values
            "step1": {
                "used": "svd+lm",
                "n_samples": 1993,
                "coverage_pct": 62.0,
                "lm": {"residual_rms": 0.004, "upper": np.eye(3).tolist()},
                "convention": "step1 = upper @ (reading - bias); |step1| = field_norm " * 4,
                "used_points": list(range(40)),
            },
        },  # fmt: skip
        figures=figures,
        config={"datasets": {"demo": "data/demo"}},
        consistency=_consistency(),
    )
    page = tmp_path / "report.html"
    page.write_text(render_report(context), encoding="utf-8")
    expected_widths = [round(50 * w) for w in (4, 3, 5)]  # dpi * width in inches

    browser = DevTools(tmp_path / "profile")
    try:
        target = browser.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = browser.send("Target.attachToTarget", {"targetId": target, "flatten": True})[
            "sessionId"
        ]
        for domain in ("Page", "Runtime", "Log", "Network"):
            browser.send(f"{domain}.enable", session=session)
        browser.send(
            "Emulation.setDeviceMetricsOverride",
            {"width": 1280, "height": 900, "deviceScaleFactor": 1, "mobile": False},
            session=session,
        )
        browser.send("Page.navigate", {"url": page.as_uri()}, session=session)
        browser.wait_for("Page.loadEventFired", session)
        probe = browser.send(
            "Runtime.evaluate",
            {
                "expression": "JSON.stringify({images: Array.from(document.images, i => "
                "[i.complete, i.naturalWidth]), h2: document.querySelectorAll('h2').length, "
                "title: document.title, width: document.documentElement.scrollWidth, "
                "clipped: Array.from(document.querySelectorAll('.scroll, pre'), "
                "e => e.scrollWidth - e.clientWidth)})",
                "returnByValue": True,
            },
            session=session,
        )["result"]["value"]
    finally:
        browser.close()

    result = json.loads(probe)
    assert result["title"] == "IMU calibration report: demo"
    assert result["h2"] == 12
    # nothing wider than the page at 1280 px, and no table scrolls inside its box
    assert result["width"] <= 1280
    assert all(extra <= 1 for extra in result["clipped"]), result["clipped"]
    # segmentation, magnetometer, validation: the order of the report
    assert result["images"] == [[True, w] for w in expected_widths]
    errors = (
        [
            e["params"]["entry"]["text"]
            for e in browser.events
            if e.get("method") == "Log.entryAdded" and e["params"]["entry"]["level"] == "error"
        ]
        + [
            json.dumps(e["params"]["args"])
            for e in browser.events
            if e.get("method") == "Runtime.consoleAPICalled" and e["params"]["type"] == "error"
        ]
        + [
            e["params"]["exceptionDetails"]["text"]
            for e in browser.events
            if e.get("method") == "Runtime.exceptionThrown"
        ]
    )
    assert errors == []
    requested = [
        e["params"]["request"]["url"]
        for e in browser.events
        if e.get("method") == "Network.requestWillBeSent"
    ]
    assert requested and all(u.startswith(("file:", "data:")) for u in requested), requested
