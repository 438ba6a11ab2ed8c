"""The rendered report in a real browser: headless Chromium loads it without errors or requests.

Chromium is driven through the DevTools protocol on a pipe (``--remote-debugging-pipe``: JSON
messages separated by NUL bytes, written to its fd 3 and read from its fd 4), so no port, no
extra package and no change to the report is needed. Skips when ``/usr/bin/chromium`` (Debian
package ``chromium``) is absent.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import re
import select
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.figure import Figure

from imucal import ImuCalibration, SensorCalibration
from imucal.io.dataset import read_dataset
from imucal.io.logs import read_log_warnings
from imucal.plots.figurefile import legibility_problems, read_text_record
from imucal.report import PARAMETER_NAMES, ReportInputs, build_report_context, render_report

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


#: What the tests read off a loaded report (JSON): the images as shown, the headings, the page's
#: width, the boxes that scroll, and the texts of the summary, the banner and the gap verdict.
PROBE = """JSON.stringify({
  images: Array.from(document.images, i => ({complete: i.complete, natural: i.naturalWidth,
    shown: i.getBoundingClientRect().width, src: i.src})),
  h2: document.querySelectorAll('h2').length, title: document.title,
  width: document.documentElement.scrollWidth,
  clipped: Array.from(document.querySelectorAll('.scroll, pre'), e => e.scrollWidth - e.clientWidth),
  summary: document.querySelector('#summary').innerText,
  banner: document.querySelector('.simulated') ? document.querySelector('.simulated').innerText : null,
  verdict: document.querySelector('#gap p.verdict') ? document.querySelector('#gap p.verdict').innerText : null,
})"""


def load_page(page: Path, profile: Path, expression: str, width: int = 1280) -> tuple[dict, list]:
    """Load ``page`` in headless Chromium ``width`` px wide, evaluate ``expression`` (which
    returns JSON) once it has loaded; returns its value and the DevTools events seen."""
    browser = DevTools(profile)
    try:
        target = browser.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = browser.send("Target.attachToTarget", {"targetId": target, "flatten": True})[
            "sessionId"
        ]
        for domain in ("Page", "Runtime", "Log", "Network"):
            browser.send(f"{domain}.enable", session=session)
        browser.send(
            "Emulation.setDeviceMetricsOverride",
            {"width": width, "height": 900, "deviceScaleFactor": 1, "mobile": False},
            session=session,
        )
        browser.send("Page.navigate", {"url": page.as_uri()}, session=session)
        browser.wait_for("Page.loadEventFired", session)
        value = browser.send(
            "Runtime.evaluate", {"expression": expression, "returnByValue": True}, session=session
        )["result"]["value"]
    finally:
        browser.close()
    return json.loads(value), browser.events


def page_errors(events: list) -> list[str]:
    """The errors a page raised: console errors, log entries at level error, exceptions."""
    return (
        [
            e["params"]["entry"]["text"]
            for e in events
            if e.get("method") == "Log.entryAdded" and e["params"]["entry"]["level"] == "error"
        ]
        + [
            json.dumps(e["params"]["args"])
            for e in events
            if e.get("method") == "Runtime.consoleAPICalled" and e["params"]["type"] == "error"
        ]
        + [
            e["params"]["exceptionDetails"]["text"]
            for e in events
            if e.get("method") == "Runtime.exceptionThrown"
        ]
    )


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
        ReportInputs(
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
    )
    page = tmp_path / "report.html"
    page.write_text(render_report(context), encoding="utf-8")
    expected_widths = [round(50 * w) for w in (4, 3, 5)]  # dpi * width in inches

    probe, events = load_page(page, tmp_path / "profile", PROBE)
    result = probe
    assert result["title"] == "IMU calibration report: demo"
    assert result["h2"] == 12
    # nothing wider than the page at 1280 px, and no table scrolls inside its box
    assert result["width"] <= 1280
    assert all(extra <= 1 for extra in result["clipped"]), result["clipped"]
    # segmentation, magnetometer, validation: the order of the report
    assert [[i["complete"], i["natural"]] for i in result["images"]] == [
        [True, w] for w in expected_widths
    ]
    errors = page_errors(events)
    assert errors == []
    requested = [
        e["params"]["request"]["url"]
        for e in events
        if e.get("method") == "Network.requestWillBeSent"
    ]
    assert requested and all(u.startswith(("file:", "data:")) for u in requested), requested


# --------------------------------------------------------------------------------------------
# Reports of real runs of the workflow: the demo, the demo without its rate table, and a
# partial public recording (Ferraris: six faces and hand turns, no rate table, no reference).

REPO = Path(__file__).resolve().parents[2]
FERRARIS = REPO / "data" / "real" / "mad_lab_ferraris"
REAL = REPO.parent / "shared" / "data" / "real" / "mad-lab-fau__imucal"
#: A number followed by a unit, as the gap verdict names the sizes of the effects it accepts.
SIZE_WITH_UNIT = re.compile(
    r"\d(?:[\d.]*)(?: × 10[⁻⁰¹²³⁴⁵⁶⁷⁸⁹]+)? (?:s|ms|%|°|ppm|cm|m/s²|rad/s)\b"
)


def _no_rate_table(folder: Path) -> Path:
    """The demo session without its rate table: the gyroscope's scale comes from eq. 36 and
    its non-orthogonality is fixed at 0."""
    folder.mkdir()
    for path in (REPO / "data" / "demo").iterdir():
        if path.name not in ("dataset.yaml", "ratetable.csv"):
            (folder / path.name).symlink_to(path)
    declared = yaml.safe_load((REPO / "data" / "demo" / "dataset.yaml").read_text())
    declared["name"] = "norate"
    del declared["ratetable"], declared["recordings"]["ratetable"]
    (folder / "dataset.yaml").write_text(yaml.safe_dump(declared, sort_keys=False))
    return folder


@pytest.fixture(scope="module")
def workflow_reports(tmp_path_factory) -> dict[str, Path]:
    """``snakemake --cores 2`` in a copy of the workflow: the reports of the three sessions."""
    root = tmp_path_factory.mktemp("browser")
    work = root / "work"
    work.mkdir()
    for name in ("Snakefile", "workflow", "config"):
        (shutil.copytree if (REPO / name).is_dir() else shutil.copy)(REPO / name, work / name)
    (work / "data").symlink_to(REPO / "data")
    datasets = {"demo": REPO / "data" / "demo", "norate": _no_rate_table(root / "norate")}
    if REAL.is_dir():
        datasets["mad_lab_ferraris"] = FERRARIS
    (work / "config" / "config.yaml").write_text(
        yaml.safe_dump({"datasets": {k: str(v) for k, v in datasets.items()}})
    )
    run = subprocess.run(
        ["snakemake", *(f"reports/{d}.html" for d in datasets), "--cores", "2", "-q"],
        cwd=work, env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True, text=True, timeout=3600, check=False,
    )  # fmt: skip
    assert run.returncode == 0, (run.stdout + run.stderr)[-4000:]
    # the run's last line names the reports it wrote
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith("Lab reports written: ") and all(f"reports/{d}.html" in last
                                                           for d in datasets), last  # fmt: skip
    return {d: work for d in datasets}


def _figure_problems(images: list[dict]) -> list[str]:
    """Every figure's texts as the page shows them: below 10 px, or overlapping."""
    problems = []
    for k, image in enumerate(images):
        png = base64.b64decode(image["src"].split(",", 1)[1])
        record = read_text_record(png)  # raises for a figure saved without its record
        assert record["width"] == image["natural"]
        problems += [f"figure {k + 1}: {p}" for p in legibility_problems(record, image["shown"])]
    return problems


@pytest.mark.slow
@pytest.mark.parametrize(
    "dataset",
    ["demo", "norate",
     pytest.param("mad_lab_ferraris", marks=pytest.mark.skipif(
         not REAL.is_dir(), reason=f"{REAL} is absent (public recording)"))],
)  # fmt: skip
def test_the_report_reads_right_at_1280_px(workflow_reports, dataset, tmp_path):
    work = workflow_reports[dataset]
    results = work / "results" / dataset
    probe, events = load_page(work / "reports" / f"{dataset}.html", tmp_path / "profile", PROBE)
    assert page_errors(events) == []
    assert probe["width"] <= 1280
    assert all(extra <= 1 for extra in probe["clipped"]), probe["clipped"]

    # every figure legible where it is shown: no text under 10 px, no two texts overlapping
    assert len(probe["images"]) >= 3
    assert _figure_problems(probe["images"]) == []

    # the banner only for simulated data (the dataset's declaration)
    simulated = read_dataset(
        datasets_folder(work, dataset)
    ).simulated is not None  # fmt: skip
    assert (probe["banner"] is not None) == simulated == (dataset != "mad_lab_ferraris")
    if simulated:
        assert probe["banner"].startswith("Simulated data.")
        assert '"truth" row' in probe["banner"]

    # the gap verdict names the size of every effect it accepts, with its unit
    diagnosis = json.loads((results / "gap" / "diagnosis.json").read_text())
    accepted = [e for e in diagnosis["effects"] if e["accepted"]]
    verdict = probe["verdict"]
    assert verdict and "_" not in verdict
    assert len(SIZE_WITH_UNIT.findall(verdict)) >= len(accepted)
    if dataset in ("demo", "norate"):  # the demo's packet loss and reference clock offset
        assert "the reference started 0.32 s before the module" in verdict
        assert "% of the packets lost in bursts of" in verdict
        assert "What is left, a gap of" in verdict and "is within noise" in verdict

    # the summary lists what was not determined and every warning of every rule's log
    summary = probe["summary"]
    calibration = json.loads((results / calibration_file(dataset)).read_text())
    for sensor in ("acc", "gyr", "mag"):
        std = (calibration.get(sensor) or {}).get("std") or {}
        for key, values in std.items():
            if key != "matrix" and any(v == 0.0 for v in values):
                assert f"{PARAMETER_NAMES[key]}" in summary and "fixed at 0" in summary
    if dataset == "norate":
        assert "non-orthogonality ξ: fixed at 0, not observable without a rate table" in summary
    logged = [w for log in sorted((results / "logs").rglob("*.log")) if log.name != "report.log"
              for w in read_log_warnings(log)]  # fmt: skip
    for w in logged:
        assert w.text.splitlines()[0].split(" (", 1)[0] in summary, w
    if not logged:
        assert "none in any stage result or rule log" in summary or "⚠" in summary


def datasets_folder(work: Path, dataset: str) -> Path:
    """The folder of a dataset of the run's config."""
    return Path(yaml.safe_load((work / "config" / "config.yaml").read_text())["datasets"][dataset])


def calibration_file(dataset: str) -> str:
    """calibration.json of the path the session takes."""
    return "partial/calibration.json" if dataset == "mad_lab_ferraris" else "calibration.json"
