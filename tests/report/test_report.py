"""The HTML lab report: content, embedded figures, self-containment, missing artifacts."""

from __future__ import annotations

import base64
import json
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from imucal import ImuCalibration, SensorCalibration
from imucal.ingest import ingest_recording, summarize_dataset
from imucal.io import write_json
from imucal.io.dataset import read_dataset
from imucal.report import (
    ReportInputs,
    build_report_context,
    collect_warnings,
    embed_figure,
    figure_section,
    flatten_fields,
    format_number,
    read_benchmarks,
    render_report,
)
from imucal.sim import simulate

SECTION_HEADINGS = (
    "Summary: how good is the calibration",
    "Session and data quality",
    "Warnings",
    "Methods used",
    "Segmentation",
    "Magnetometer",
    "Accelerometer",
    "Gyroscope",
    "Tables I and II",
    "Validation against the reference",
    "Provenance",
)
_VOID = {"meta", "img", "br", "hr", "link", "input", "col", "wbr", "source"}


class _Collector(HTMLParser):
    """Tags, attributes, headings and nesting errors of an HTML document."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict]] = []
        self.headings: list[str] = []
        self.ids: list[str] = []
        self.errors: list[str] = []
        self._stack: list[str] = []
        self._heading: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append((tag, attrs))
        if "id" in attrs:
            self.ids.append(attrs["id"])
        if tag not in _VOID:
            self._stack.append(tag)
        if tag == "h2":
            self._heading = []

    def handle_endtag(self, tag):
        if not self._stack or self._stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self._stack[-1:]}")
        else:
            self._stack.pop()
        if tag == "h2" and self._heading is not None:
            self.headings.append("".join(self._heading).strip())
            self._heading = None

    def handle_data(self, data):
        if self._heading is not None:
            self._heading.append(data)


def parse(html: str) -> _Collector:
    c = _Collector()
    c.feed(html)
    c.close()
    return c


def _png(path: Path, width_in: float) -> Path:
    fig = Figure(figsize=(width_in, 2.0))
    fig.subplots().plot(np.sin(np.linspace(0, 6, 50)))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=50)
    return path


@pytest.fixture(scope="module")
def artifacts(tmp_path_factory) -> dict:
    """A small set of artifacts of one simulated dataset, as the workflow writes them."""
    root = tmp_path_factory.mktemp("report")
    session = simulate(root / "raw", preset="demo", seed=1, static_s=20, name="demo")
    dataset = read_dataset(root / "raw")
    recordings = {
        name: ingest_recording(path, name, dataset, "test")
        for name, path in dataset.recordings.items()
    }
    summary = summarize_dataset(recordings, dataset.name)
    results = root / "results" / "demo"
    write_json(summary, results / "ingest" / "summary.json")

    truth = session.truth_dict()
    units = {"acc": "m/s^2", "gyr": "rad/s", "mag": "normalised"}
    calibration = ImuCalibration(
        *(
            SensorCalibration(
                s,
                truth[s]["bias"],
                truth[s]["matrix"],
                units[s],
                std={"bias": [1.5e-4, 2.5e-4, 3.5e-4], "matrix": np.full((3, 3), 2e-5)}
                if s != "mag"
                else {},
                method=f"{s} method of the test",
            )
            for s in ("acc", "gyr", "mag")
        )
    )
    write_json(calibration.to_dict(), results / "calibration.json")
    write_json(
        {
            "method": "paper way and full-phase way",
            "coverage_pct": 87.25,
            "step1": {"rms": 0.0012345678, "center": [0.1, 0.2, 0.3]},
            "phases": [{"label": "x", "n": 120}, {"label": "y", "n": 118}],
            "warnings": ["sphere coverage 87 % is below 90 %"],
        },
        results / "mag.json",
    )
    write_json(
        {"fit": {"rms_m_s2": 0.0213, "warnings": ["position p07 clipped"]}}, results / "acc.json"
    )
    write_json({"bias_rad_s": [0.0027, 0.1605, 0.066]}, results / "gyr.json")
    write_json(
        {"acc": {"rmse_m_s2": 0.0456789, "time_shift_s": 0.031}, "mounting_deg": [1, 2, 3]},
        results / "validation.json",
    )
    pd.DataFrame(
        {
            "table": ["I", "I", "I", "II", "II"],
            "row": ["paper w. tools", "this run (rate table)", "truth", "paper w. tools", "truth"],
            "x": [0.0027, 0.00271234, 0.0027, 1.1526, 1.1526],
            "y": [0.1605, 0.16049, 0.1605, 1.1327, 1.1327],
            "z": [0.066, 0.06612, 0.066, 1.1425, 1.1425],
        }
    ).to_csv(results / "tables.csv", index=False)
    figures = [
        _png(results / "segments" / "rotation3d.png", 4),
        _png(results / "figures" / "mag_raw.png", 3),
        _png(results / "figures" / "acc_cube.png", 5),
        _png(results / "figures" / "gyr_table.png", 4),
        _png(results / "figures" / "validation.png", 6),
    ]
    bench = root / "benchmarks" / "demo"
    bench.mkdir(parents=True)
    (bench / "fit_mag.tsv").write_text(
        "s\th:m:s\tmax_rss\tmax_vms\n1.0\t0:00:01\t100.0\t200\n3.0\t0:00:03\t120.5\t210\n"
    )
    (bench / "fit_acc.tsv").write_text("s\th:m:s\tmax_rss\n0.5\t0:00:00\t90.0\n")
    return {
        "root": root,
        "summary": summary,
        "results": results,
        "calibration": calibration.to_dict(),
        "figures": figures,
        "benchmarks": [bench / "fit_mag.tsv", bench / "fit_acc.tsv"],
        "recordings": dataset.recordings,
    }


def full_context(a: dict) -> dict:
    """Context with every artifact of the fixture given."""
    r = a["results"]
    kwargs = {
        "dataset": "demo",
        "summary": r / "ingest" / "summary.json",
        "calibration": r / "calibration.json",
        "mag_result": r / "mag.json",
        "acc_result": r / "acc.json",
        "gyr_result": r / "gyr.json",
        "validation": r / "validation.json",
        "tables": r / "tables.csv",
        "figures": a["figures"],
        "benchmarks": a["benchmarks"],
        "config": {"datasets": {"demo": "data/demo"}, "lowpass": {"cutoff_hz": 5.0}},
        "git_commit": "0123abcd",
        "snakemake_version": "9.9.9",
        "generated": "2024-01-02T03:04:05+00:00",
    }
    return build_report_context(ReportInputs(**kwargs))


@pytest.fixture(scope="module")
def report(artifacts) -> str:
    return render_report(full_context(artifacts))


# --------------------------------------------------------------------------------------------


def test_sections_in_order_and_table_of_contents(report):
    doc = parse(report)
    assert doc.errors == []
    assert doc.headings == list(SECTION_HEADINGS)
    links = [a["href"] for tag, a in doc.tags if tag == "a"]
    # the contents list every section once; the summary links its warnings to their section
    # and a sensor's undetermined parameters to its section
    assert len(set(links)) == len(SECTION_HEADINGS)
    sensors = [f"#{s}" for s in ("accelerometer", "gyroscope", "magnetometer")]
    summary_links = links.count("#warnings") - 1 + sum(links.count(s) - 1 for s in sensors)
    assert len(links) - summary_links == len(SECTION_HEADINGS)
    assert all(h.startswith("#") and h[1:] in doc.ids for h in links)


def test_session_data_quality(report, artifacts):
    summary = artifacts["summary"]
    imu_s = sum(r["duration_s"] for n, r in summary["recordings"].items() if n != "reference")
    assert f"last {format_number(imu_s)} s in total" in report
    for rec in summary["recordings"].values():
        assert rec["sha256"] in report
        assert f"<code>{rec['source']}</code>" in report
        assert f'<td class="num">{rec["rows"]}</td>' in report
        assert f"{rec['n_gaps']} gaps" in report or rec["n_gaps"] == 0
    assert f"{summary['lost_packets']} lost packets" in report
    assert summary["lost_packets"] > 0  # the demo preset drops packets: gaps are shown
    first_gap = summary["recordings"]["rotation3d"]["gaps"][0]
    assert f'<td class="num">{format_number(first_gap["t_s"], 6)}</td>' in report


def test_parameters_with_standard_deviations(report, artifacts):
    cal = artifacts["calibration"]
    bias = cal["acc"]["bias"][1]
    assert f"{format_number(bias)} ± {format_number(2.5e-4, 2)}" in report
    assert f"{format_number(-0.218)} ± 0.00025" in report  # the demo truth's acc bias y
    matrix = cal["gyr"]["matrix"][0][0]
    assert f"{format_number(matrix)} ± 2e-05" in report
    for value in cal["mag"]["scale"]:  # no std known for the magnetometer
        assert f'<td class="num">{format_number(value)}</td>' in report
    assert "No standard deviation is known for: bias o, matrix" in report
    for s in ("acc", "gyr", "mag"):
        assert f"{s} method of the test" in report
    assert "paper way and full-phase way" in report


def test_stage_results_rendered_generically(report):
    assert "<code>step1.rms</code>" in report
    assert format_number(0.0012345678) == "0.0012346"
    assert '<td class="num">0.0012346</td>' in report
    assert '<td class="num">[0.1, 0.2, 0.3]</td>' in report
    assert "<code>phases</code>" in report  # list of dicts -> table of its own
    assert "<code>acc.rmse_m_s2</code>" in report  # validation, nested
    assert '<td class="num">0.045679</td>' in report


def test_warnings_collected_from_every_stage(report):
    assert "sphere coverage 87 % is below 90 %" in report
    assert "position p07 clipped" in report
    assert "<code>fit.warnings</code>" in report
    assert report.count('class="warning"') == 2
    assert "<code>warnings</code></th>" not in report  # not repeated in the key/value tables


def test_paper_tables_rendered(report):
    assert "Table I: gyroscope bias (rad/s)" in report
    assert "Table II: gyroscope scale (1)" in report
    assert "this run (rate table)" in report
    assert '<td class="num">0.0027123</td>' in report
    assert "No ground truth" not in report


def test_every_figure_embedded_once_and_decodes(report, artifacts):
    doc = parse(report)
    imgs = [a for tag, a in doc.tags if tag == "img"]
    assert len(imgs) == len(artifacts["figures"])
    decoded = []
    for a in imgs:
        head, _, payload = a["src"].partition(",")
        assert head == "data:image/png;base64"
        decoded.append(base64.b64decode(payload, validate=True))
        assert a["alt"]
    assert sorted(decoded) == sorted(p.read_bytes() for p in artifacts["figures"])
    assert report.count("<figcaption>") == len(imgs)
    # numbered in the order they appear, whatever order they were given in
    numbers = [int(x) for x in (i["id"].removeprefix("fig-") for _, i in doc.tags if _ == "figure")]
    assert numbers == list(range(1, len(imgs) + 1))
    assert "paper Fig. 15" in report and "paper Fig. 4" in report


def test_self_contained_no_external_urls(report):
    doc = parse(report)
    for tag, attrs in doc.tags:
        for name in ("src", "href"):
            if name in attrs:
                assert "http" not in attrs[name] and "//" not in attrs[name].split(",")[0]
                assert attrs[name].startswith(("#", "data:"))
    assert "<script" not in report and "<link" not in report and "@import" not in report
    assert "url(" not in report
    meta = [a for t, a in doc.tags if t == "meta" and a.get("http-equiv")]
    assert meta[0]["content"].startswith("default-src 'none'; img-src data:")


def test_provenance(report):
    assert "0123abcd" in report and "9.9.9" in report
    assert "lowpass:\n  cutoff_hz: 5.0" in report
    # two repeats of fit_mag averaged, longest first
    assert report.index("<code>fit_mag</code>") < report.index("<code>fit_acc</code>")
    assert '<td class="num">2</td><td class="num">2</td><td class="num">120.5</td>' in report
    assert '<td class="num">2.5</td>' in report  # total


def test_missing_artifacts_give_sentences(artifacts):
    summary = json.loads(json.dumps(artifacts["summary"]))
    for name in ("reference", "ratetable"):
        del summary["recordings"][name]
    tables = pd.read_csv(artifacts["results"] / "tables.csv")
    html = render_report(
        build_report_context(
            ReportInputs(
                dataset="demo",
                summary=summary,
                calibration=artifacts["calibration"],
                tables=tables[tables["row"] != "truth"],
                git_commit="unknown",
            )
        )
    )
    doc = parse(html)
    assert doc.errors == []
    assert doc.headings == list(SECTION_HEADINGS)
    assert "<img" not in html
    assert "The dataset has no reference recording" in html
    assert "No validation: the dataset has no reference recording" in html
    assert html.count("The dataset has no rate-table recording") == 2  # session, gyroscope
    assert "No ground truth (truth.json) for this dataset: Table I" in html
    assert "No ground truth (truth.json) for this dataset: Table II" in html
    for s in ("mag", "acc", "gyr"):
        assert f"No stage result ({s}.json) was given." in html
    assert "No segmentation figure was given." in html
    assert "No benchmark files were given" in html
    assert "No configuration was given." in html
    assert "No warning: none in any stage result and none in any rule's log." in html
    assert "<strong>Warnings of the run:</strong> none in any stage result or rule log." in html

    no_tables = render_report(
        build_report_context(
            ReportInputs(dataset="demo", summary=summary, calibration=artifacts["calibration"])
        )
    )
    assert "No tables.csv was given" in no_tables


def test_partial_session_lists_stages_and_uncalibrated_sensors(artifacts):
    calibration = dict(artifacts["calibration"])
    del calibration["acc"]
    calibration["missing"] = {"acc": "no stage of this sensor could run: acc_cube: needs poses"}
    stages = {
        "stages": [
            {
                "stage": "mag_step1",
                "what": "magnetometer ellipsoid fit",
                "status": "run",
                "reason": "ran",
            },
            {
                "stage": "acc_cube",
                "what": "accelerometer fit",
                "status": "skipped",
                "reason": "not applicable: needs >= 9 static poses",
            },
        ]
    }
    html = render_report(
        build_report_context(
            ReportInputs(
                dataset="demo", summary=artifacts["summary"], calibration=calibration, stages=stages
            )
        )
    )
    doc = parse(html)
    assert doc.errors == []
    assert "Stages run and skipped" in doc.headings
    assert "not applicable: needs &gt;= 9 static poses" in html
    assert "Not calibrated: no stage of this sensor could run" in html
    assert "not calibrated: no stage of this sensor could run" in html  # methods table
    with pytest.raises(ValueError, match="gives no reason"):
        del calibration["missing"]
        build_report_context(
            ReportInputs(dataset="demo", summary=artifacts["summary"], calibration=calibration)
        )


def test_reference_without_validation_says_so(artifacts):
    html = render_report(
        build_report_context(
            ReportInputs(
                dataset="demo", summary=artifacts["summary"], calibration=artifacts["calibration"]
            )
        )
    )
    assert "although the dataset has a reference recording" in html


def test_text_is_escaped(artifacts):
    html = render_report(
        build_report_context(
            ReportInputs(
                dataset="demo",
                summary=artifacts["summary"],
                calibration=artifacts["calibration"],
                mag_result={"warnings": ["<script>alert(1)</script> & more"]},
            )
        )
    )
    assert "<script>" not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt; &amp; more" in html


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (0.0027, "0.0027"),
        (1.1526000000000003, "1.1526"),
        (-0.218, "-0.218"),
        (9.81, "9.81"),
        (0.012345678, "0.012346"),
        (4.2e-5, "4.2e-05"),
        (123456.0, "123456"),
        (123456.7, "1.2346e+05"),
        (8084, "8084"),
        (0.0, "0"),
        (float("nan"), "n/a"),
        (None, "n/a"),
        (True, "yes"),
        (np.float32(0.5), "0.5"),
        (np.int64(7), "7"),
    ],
)
def test_format_number(value, text):
    assert format_number(value) == text


def test_flatten_fields_and_warnings():
    data = {
        "a": 1.23456789,
        "b": {"m": [[1.0, 0.0], [0.0, 1.0]], "warnings": ["w1"]},
        "long": list(range(20)),
        "runs": [{"label": "x+100", "err": 0.5}, {"label": "x-100", "extra": "s"}],
        "deep": [{"warnings": ["w2", "w3"]}],
        "empty": {},
    }
    flat = flatten_fields(data)
    assert flat["rows"] == [
        ("a", "1.2346"),
        ("b.m", "[[1, 0], [0, 1]]"),
        ("long", "20 values, 0 ... 19"),
        ("empty", "(empty)"),
    ]
    runs, deep = flat["records"]
    assert runs["columns"] == ["label", "err", "extra"]
    assert runs["rows"] == [["x+100", "0.5", ""], ["x-100", "", "s"]]
    assert deep["rows"] == [["[w2, w3]"]]  # inside a record the list stays visible
    assert [(w["where"], w["text"]) for w in collect_warnings(data, "x.json")] == [
        ("b.warnings", "w1"),
        ("deep[0].warnings", "w2"),
        ("deep[0].warnings", "w3"),
    ]


def test_read_benchmarks_labels_and_means(tmp_path):
    a = tmp_path / "results" / "demo" / "benchmarks" / "ingest" / "cube.tsv"
    b = tmp_path / "benchmarks" / "demo" / "fit_gyr.tsv"
    c = tmp_path / "elsewhere" / "plain.tsv"
    for path, text in ((a, "s\tmax_rss\n0.2\t50\n0.4\t70\n"), (b, "s\n1.5\n"), (c, "s\n0.1\n")):
        path.parent.mkdir(parents=True)
        path.write_text(text)
    table = read_benchmarks([a, b, c], dataset="demo")
    assert table["rule"].tolist() == ["fit_gyr", "ingest/cube", "plain"]
    assert table["s"].tolist() == pytest.approx([1.5, 0.3, 0.1])
    assert table["repeats"].tolist() == [1, 2, 1]
    assert table["max_rss_mb"].iloc[1] == 70
    assert np.isnan(table["max_rss_mb"].iloc[0])
    labelled = read_benchmarks({"my rule": a}, dataset="demo")
    assert labelled["rule"].tolist() == ["my rule"]
    bad = tmp_path / "bad.tsv"
    bad.write_text("seconds\n1\n")
    with pytest.raises(ValueError, match="expected a Snakemake benchmark file"):
        read_benchmarks([bad], dataset="demo")


def test_figure_sections():
    assert figure_section("results/d/segments/cube.png") == "segmentation"
    assert figure_section("results/d/figures/mag_step1.png") == "magnetometer"
    assert figure_section("results/d/figures/cube-positions.png") == "accelerometer"
    assert figure_section("results/d/figures/ratetable_errors.png") == "gyroscope"
    assert figure_section("results/d/figures/validation.png") == "validation"
    assert figure_section("results/d/figures/whatever.png") == "other"


def test_bad_inputs_are_refused(tmp_path, artifacts):
    fake = tmp_path / "fake.png"
    fake.write_bytes(b"GIF89a not a png")
    with pytest.raises(ValueError, match="PNG signature"):
        embed_figure(fake)
    with pytest.raises(ValueError, match="suffix '.jpg'"):
        embed_figure(tmp_path / "photo.jpg")
    with pytest.raises(FileNotFoundError, match="figure not found"):
        embed_figure(tmp_path / "absent.png")
    svg = tmp_path / "a.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="2" height="2"/>')
    assert embed_figure(svg).startswith("data:image/svg+xml;base64,")
    calibration = dict(artifacts["calibration"])
    del calibration["gyr"]
    with pytest.raises(ValueError, match=r"calibration lacks the sensors \['gyr'\]"):
        build_report_context(
            ReportInputs(dataset="demo", summary=artifacts["summary"], calibration=calibration)
        )
    with pytest.raises(ValueError, match=r"missing \['z'\]"):
        build_report_context(
            ReportInputs(
                dataset="demo",
                summary=artifacts["summary"],
                calibration=artifacts["calibration"],
                tables=pd.DataFrame({"table": ["I"], "row": ["r"], "x": [1.0], "y": [2.0]}),
            )
        )


def test_unknown_std_entries_print_the_value_alone(artifacts):
    calibration = json.loads(json.dumps(artifacts["calibration"]))
    calibration["acc"]["std"]["bias"] = [1e-4, None, 2e-4]  # NaN is written as null
    context = build_report_context(
        ReportInputs(dataset="demo", summary=artifacts["summary"], calibration=calibration)
    )
    acc = next(s for s in context["sensors"] if s["id"] == "accelerometer")
    bias = calibration["acc"]["bias"]
    assert acc["parameters"]["rows"][0]["cells"] == [
        f"{format_number(bias[0])} ± 0.0001",
        format_number(bias[1]),
        f"{format_number(bias[2])} ± 0.0002",
    ]


def test_gap_section_of_an_unscored_and_of_a_fallback_diagnosis(artifacts, tmp_path):
    """A diagnosis that scored nothing (no static recording) and one that fell back to the
    static recording both render, with the reason, what was noted and the hands."""
    from imucal.gap.static import unscored_diagnosis

    unscored = tmp_path / "unscored.json"
    unscored.write_text(
        json.dumps(unscored_diagnosis("demo", "the session has no static recording"))
    )
    fallback = tmp_path / "fallback.json"
    diag = unscored_diagnosis("demo", "no stream")
    diag.update(fallback="the calibration chain stopped (gyro clipped)", noted=["saturation"],
                saturation={"clip_fraction": {"gyr": 0.12}}, held_by_hand=["cube"])  # fmt: skip
    fallback.write_text(json.dumps(diag))
    for path, texts in (
        (unscored, ["No location could be scored: the session has no static recording"]),
        (fallback, ["The full diagnosis could not run:", "gyr 12 %", "Held by hand"]),
    ):
        context = build_report_context(ReportInputs(
            dataset="demo", summary=artifacts["summary"], calibration=artifacts["calibration"],
            gap=[path],
        ))  # fmt: skip
        html = render_report(context)
        assert parse(html).errors == []
        for text in texts:
            assert text in html, text


def test_workflow_commit_is_the_checkout_head_or_unknown(tmp_path) -> None:
    import subprocess

    from imucal.report.provenance import workflow_commit

    assert workflow_commit(tmp_path) == "unknown"  # not a git checkout
    here = Path(__file__).parent
    head = subprocess.run(
        ["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True, text=True
    )
    if head.returncode == 0:
        assert workflow_commit(here) == head.stdout.strip()


RULES_DIR = Path(__file__).resolve().parents[2] / "workflow" / "rules"


def _report_outputs_of_rules() -> list[tuple[str, str]]:
    """(output path, caption path relative to the rule file) of every ``report(...)`` output
    of the rules, and of the stage rules generated from the graph."""
    import re

    from imucal.pipeline.graph import FULL_PROTOCOL

    pairs = []
    for rules in sorted(RULES_DIR.glob("*.smk")):
        text = rules.read_text(encoding="utf-8")
        pairs += re.findall(r'report\(\s*"([^"]+)",\s*caption="([^"]+)"', text)
    # the stage rules are generated from the graph (workflow/rules/stages.smk)
    pairs += [
        (f"results/{{dataset}}/{out.path}", f"../../{out.caption}")
        for node in FULL_PROTOCOL.values()
        for out in node.outputs
    ]
    return pairs


def test_every_figure_of_the_rules_has_the_lab_reports_caption_file():
    """One caption per figure: Snakemake's report reads the file the lab report reads."""
    from docutils.core import publish_parts

    from imucal.report.figures import CAPTIONS_DIR, DEFAULT_CAPTIONS

    pairs = _report_outputs_of_rules()
    figures = [(out, cap) for out, cap in pairs if out.endswith((".png", ".svg"))]
    assert len(figures) >= 11
    for out, caption in pairs:
        path = (RULES_DIR / caption).resolve()
        assert path.is_file(), f"{out}: caption {caption} not found"
        html = publish_parts(
            path.read_text(encoding="utf-8"),
            writer_name="html",
            settings_overrides={"report_level": 2, "halt_level": 2},
        )["body"]
        assert html.strip(), f"{caption} renders empty"
    for out, caption in figures:
        if "/gap/" in out:
            continue  # the diagnosis's figures share the diagnosis's caption
        stem = Path(out).stem
        assert (RULES_DIR / caption).resolve() == CAPTIONS_DIR / f"{stem}.rst", out
        assert stem in DEFAULT_CAPTIONS
        assert "\\" not in DEFAULT_CAPTIONS[stem]


def test_the_simulated_banner_only_for_simulated_data(artifacts):
    """A dataset that declares itself simulated gets the banner with what rendered it and what
    its truth rows are; a recorded one gets neither."""
    kwargs = {"dataset": "demo", "summary": artifacts["summary"],
              "calibration": artifacts["calibration"],
              "tables": artifacts["results"] / "tables.csv"}  # fmt: skip
    simulated = render_report(
        build_report_context(
            ReportInputs(
                **kwargs, simulated={"by": "imucal.sim, preset demo", "truth": "/x/truth.json"}
            )
        )
    )
    assert parse(simulated).errors == []
    assert '<div class="simulated"' in simulated
    assert "rendered by a simulator (imucal.sim, preset demo), not measured" in simulated
    assert "<code>truth.json</code> in the dataset's folder" in simulated
    assert "the value the simulator rendered the data from" in simulated
    recorded = render_report(build_report_context(ReportInputs(**kwargs)))
    assert 'class="simulated"' not in recorded and "Simulated data" not in recorded
    assert "the value in the dataset's truth.json" in recorded


def test_the_summary_lists_undetermined_parameters_and_every_logged_warning(artifacts, tmp_path):
    """A gyroscope without a rate table has its non-orthogonality fixed at 0 (one axis at
    -7.6e-19 from the decomposition): the summary says so; the warnings of every rule's log
    reach the summary and the Warnings section with their counts."""
    calibration = json.loads(json.dumps(artifacts["calibration"]))
    gyr = calibration["gyr"]
    gyr["xi_rad"] = [-7.59e-19, 0.0, 3.1e-18]
    gyr["std"] = {"bias": [1e-5] * 3, "matrix": np.full((3, 3), 1e-4).tolist(),
                  "scale": [1e-4] * 3, "xi_rad": [0.0] * 3, "alpha_rad": [1e-3] * 3}  # fmt: skip
    logs = tmp_path / "results" / "demo" / "logs"
    logs.mkdir(parents=True)
    nyquist = "mag: cutoff 5 Hz is not below its Nyquist frequency (5 Hz at 10 Hz); kept unfiltered"
    (logs / "gap_diagnose.log").write_text(
        f"INFO:root:start\n{f'WARNING:imucal.segments.filtering:{nyquist}' + chr(10)}" * 39
    )
    (logs / "segment.log").write_text("INFO:root:segments written\n")
    (logs / "lowpass").mkdir()
    (logs / "lowpass" / "rotation3d.log").write_text(
        f"WARNING:imucal.segments.filtering:{nyquist}\n"
    )
    summary = json.loads(json.dumps(artifacts["summary"]))
    del summary["recordings"]["ratetable"]
    html = render_report(
        build_report_context(ReportInputs(
            dataset="demo", summary=summary, calibration=calibration,
            logs=[logs / "gap_diagnose.log", logs / "segment.log",
                  logs / "lowpass" / "rotation3d.log"],
        ))
    )  # fmt: skip
    assert parse(html).errors == []
    summary = html[html.index('id="summary"') : html.index('<nav class="toc"')]
    assert (
        "<strong>Not determined:</strong> non-orthogonality ξ: fixed at 0, not observable "
        "without a rate table" in summary
    )
    # one message from two logs: once in the summary, counted over both
    assert (
        'mag: cutoff 5 Hz is not below its Nyquist frequency (40 times) <span class="note">'
        "(logs/gap_diagnose.log, logs/lowpass/rotation3d.log)" in summary
    )
    assert 'Warnings of the run:</strong> <span class="flagmark">⚠</span> 1' in summary
    assert "none of its own" in summary  # accelerometer and gyroscope: the run has one
    assert ">none<" not in summary
    section = html[html.index('<section id="warnings">') :]
    assert "logs/gap_diagnose.log, <code>imucal.segments.filtering</code>, 39 times" in section
    # the gyroscope's table prints the fixed parameter as 0, not as -7.59e-19
    assert "-7.59e-19" not in html and "0 (fixed, not observable)" in html


def test_files_are_named_relative_to_the_dataset_and_broken_at_separators(artifacts):
    context = build_report_context(ReportInputs(
        dataset="demo", summary=artifacts["summary"], calibration=artifacts["calibration"],
        dataset_folder=artifacts["root"] / "raw",
    ))  # fmt: skip
    html = render_report(context)
    # the folder once, as the config gives it; each file relative to it
    assert html.count(str(artifacts["root"])) == 1
    assert f"folder, <code>{artifacts['root'] / 'raw'}</code>" in html
    assert '<td class="text"><code>mtx_rotation3d.txt</code></td>' in html
    # a file name breaks only after its separators, never mid-word
    assert '<code class="filename" title="rotation3d.csv">rotation3d.<wbr>csv</code>' in html
    assert "paths relative to the dataset's folder" in html


def test_the_angle_between_force_and_field_gives_the_dip():
    from imucal.report.digest import validation_tables

    dip = {"calibrated": {"mean_deg": 153.97, "std_deg": 0.27}}
    tables = validation_tables({"metrics": {"calibrated": {}}, "dip": dip})
    row = tables[0]["rows"][0]
    assert tables[0]["title"].startswith("Angle between the specific force and the magnetic")
    assert row["quantity"] == "angle, calibrated" and row["cells"] == ["154 ± 0.27"]
    assert row["note"] == "dip 63.97° (the angle less 90°)"


def test_noise_tables_carry_the_units_in_their_headers(tmp_path):
    from imucal.report.sections import noise_section

    term = {"resolved": True, "value": 2e-4, "std": 1e-5, "unit": "(m/s^2)/sqrt(Hz)"}
    noise = {"recording": "static", "duration_s": 120.0, "rate_hz": 100.0, "level": 0.683,
             "terms": ["N"], "sensors": {"acc": {"axes": {"x": {"terms": {"N": term},
                                                              "reduced_chi2": 1.1}}}}}  # fmt: skip
    path = tmp_path / "noise.json"
    path.write_text(json.dumps(noise))
    table = noise_section([path])["tables"][0]
    assert table["title"] == "Accelerometer"
    assert table["headers"] == [
        {"term": "N", "name": "N, white noise (density)", "unit": "(m/s²)/√Hz"}
    ]
    assert table["rows"][0]["cells"]["N"] == "0.0002 ± 1e-05"


def test_the_consistency_check_given_as_its_file_is_the_section_of_the_check_given_as_a_dict(
    artifacts, tmp_path
):
    from imucal.report.consistency import consistency_rows

    check = {"sensors": {"gyr": {"stage": "gyr_bias", "reason": "halves: part 1 shipped no "
                                 "gyroscope", "inflation": {"bias": 1.5, "matrix": 1.0}}}}  # fmt: skip
    path = tmp_path / "consistency.json"
    path.write_text(json.dumps(check))
    sections = [
        build_report_context(
            ReportInputs(
                dataset="demo",
                summary=artifacts["summary"],
                calibration=artifacts["calibration"],
                consistency=given,
            )
        )["consistency"]
        for given in (check, path)
    ]
    assert sections[1] == sections[0]
    assert sections[0]["rows"] == consistency_rows(check)
