"""Figures a paper can use: one saving function (PNG at --dpi, SVG), the run plot's marks, colours and legend,
readable trajectory panels, categorical pedestrian counts, intervals on the score shares, and the screenshot
script's browser search and full-page capture."""

from __future__ import annotations

import io
import os
import stat
from functools import cache
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.container import ErrorbarContainer

from analysis.figures import (
    correlation_map_figure,
    design_evaluation_figure,
    min_distance_figure,
    residuals_figure,
    score_distribution_figure,
    shares_figure,
    trajectories_figure,
)
from analysis.intervals import wilson
from robot_logs.figure_files import BODY_TEXT_PT, FORMATS, PRINT_COLUMN_IN, Rendered, figure_bytes
from robot_logs.run_log import LoggedRun
from tests.support.scripts import load_script
from tests.support.system_packages import need
from trials.run_figure import MARK_EVERY_S, ROBOT_COLOUR, mark_indices, run_figure

screenshot_report = load_script("screenshot_report")


def logged_run(pedestrians: int = 12) -> LoggedRun:
    """A 12 s straight run at 0.1 s steps, with `pedestrians` people crossing it; the first is unseen for 2 s."""
    t = np.round(np.arange(0.0, 12.05, 0.1), 4)
    pose = np.column_stack([0.8 * t - 5.0, np.zeros_like(t), np.zeros_like(t)])
    people = np.stack([np.column_stack([np.full_like(t, j - 3.0), 0.5 * t - 3.0]) for j in range(pedestrians)], axis=1)
    people[:20, 0] = np.nan
    return LoggedRun({}, t, pose, np.zeros((len(t), 2)), tuple(range(1, pedestrians + 1)), people,
                     [(0.0, "start", ""), (12.0, "goal", "")], 30)


def size(png: bytes) -> tuple[int, int]:
    return mpimg.imread(io.BytesIO(png), format="png").shape[:2]


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_one_saving_function_gives_png_at_the_dpi_and_a_stable_svg(tmp_path: Path):
    image = score_distribution_figure({"A": [1, 3, 10]}, None, "scores")
    low, high = size(image.png(100)), size(image.png(200))
    assert high[0] == pytest.approx(2 * low[0], abs=3) and high[1] == pytest.approx(2 * low[1], abs=3)
    assert image.svg() == image.svg() and b"<dc:date>" not in image.svg()  # no date: the same bytes each time
    panels = [(f"{i}. RUN\n4 ped", "A", np.zeros((2, 2)) + i, []) for i in range(5)]
    laid_out = trajectories_figure(panels, {"A": "#1f77b4"}, "arm")  # constrained layout: settled once
    before = laid_out.svg()
    laid_out.png(300)
    assert laid_out.svg() == before
    files = image.files(tmp_path / "scores", 150)
    assert list(files) == [tmp_path / f"scores{suffix}" for suffix in FORMATS]
    assert files[tmp_path / "scores.png"][:8] == b"\x89PNG\r\n\x1a\n" and b"<svg" in files[tmp_path / "scores.svg"]
    with pytest.raises(ValueError, match="figures are saved as .png, .svg, not .jpg"):
        figure_bytes(image.figure, ".jpg")


def test_time_marks_fall_every_two_seconds():
    run = logged_run()
    assert MARK_EVERY_S == 2.0
    assert list(run.time[mark_indices(run.time)]) == [0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0]
    assert len(mark_indices(np.zeros(0))) == 0


def test_the_robot_has_a_colour_no_pedestrian_gets_and_the_legend_sits_outside_the_data():
    figure = run_figure(logged_run(12), "run X", (5.0, 0.0), (0.0, 0.0)).figure
    (axes,) = figure.axes
    lines = {line.get_label(): line for line in axes.get_lines()}
    robot = to_rgba(lines["robot"].get_color())
    people = [to_rgba(line.get_color()) for label, line in lines.items() if label.startswith("pedestrian ")]
    assert robot == to_rgba(ROBOT_COLOUR) and len(people) == 12 and robot not in people
    marks = [line for line in axes.get_lines() if line.get_marker() == "o" and to_rgba(line.get_color()) == robot and len(line.get_xdata())]
    assert len(marks) == 1 and len(marks[0].get_xdata()) == 7  # 0, 2, ..., 12 s
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(figure).get_renderer()
    figure.draw(renderer)
    box, data = axes.get_legend().get_window_extent(renderer), axes.get_window_extent(renderer)
    assert box.x0 >= data.x1  # beside the axes: it cannot hide a path
    assert box.x0 - data.x1 < 0.1 * figure.dpi and box.y1 == pytest.approx(data.y1, abs=1)  # against them, level with their top


def test_trajectory_panels_read_at_the_body_size_and_no_title_is_clipped():
    path = np.column_stack([np.linspace(-5, 5, 50), np.zeros(50)])
    panels = [(f"{i + 1}. RUN{i:02d} | Arm {'AB'[i % 2]}\n4 ped | score 3", "AB"[i % 2], path, [path[::-1] + [0, 1]]) for i in range(14)]
    figure = trajectories_figure(panels, {"A": "#1f77b4", "B": "#d62728"}, "arm").figure
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(figure).get_renderer()
    figure.draw(renderer)
    shown = [axes for axes in figure.axes if axes.get_visible()]
    assert len(shown) == 14 and len(figure.axes) == 16  # four a row; the last row's two spare panels hidden
    page = figure.bbox
    for axes in shown:
        ticks = axes.xaxis.get_major_ticks() + axes.yaxis.get_major_ticks()
        assert ticks and min(tick.label1.get_fontsize() for tick in ticks) >= BODY_TEXT_PT
        title = axes.title.get_window_extent(renderer)
        assert axes.title.get_fontsize() >= BODY_TEXT_PT and page.x0 <= title.x0 and title.x1 <= page.x1 and title.y1 <= page.y1
    for first, second in zip(shown, shown[1:]):  # titles never run into their neighbours
        a, b = first.title.get_window_extent(renderer), second.title.get_window_extent(renderer)
        assert not a.overlaps(b)


def test_pedestrian_counts_are_categories():
    points = [("A", 2, 0.8), ("A", 6, 0.3), ("B", 2, 0.9), ("B", 4, 0.5), ("B", 6, 0.2)]
    axes = min_distance_figure(points, ["A", "B"], "gap", 0.45).figure.axes[0]
    assert [t.get_text() for t in axes.get_xticklabels()] == ["2", "4", "6"]
    assert list(axes.get_xticks()) == [0, 1, 2]  # evenly spaced whatever the counts
    a_points = next(line for line in axes.get_lines() if line.get_label() == "A")
    assert list(np.round(a_points.get_xdata(), 3)) == [-0.2, 1.8]


def test_score_shares_carry_wilson_intervals():
    axes = score_distribution_figure({"A": [1, 3, 10], "B": [0, 5, 9]}, None, "scores").figure.axes[0]
    bars = [c for c in axes.containers if not isinstance(c, ErrorbarContainer)]
    heights = [round(p.get_height(), 6) for p in bars[0].patches]
    assert heights == [round(100 * 1 / 14, 6), round(100 * 3 / 14, 6), round(100 * 10 / 14, 6)]
    caps = [c for c in axes.containers if isinstance(c, ErrorbarContainer)]
    segments = caps[0].lines[2][0].get_segments()
    natural = wilson(10, 14)
    assert segments[2][:, 1] == pytest.approx([100 * natural.low, 100 * natural.high])
    assert len(caps) == 2 and "Wilson 95 %" in axes.get_ylabel()


def test_the_screenshot_script_finds_debians_headless_shell(tmp_path: Path, monkeypatch):
    shell = tmp_path / "chromium-headless-shell"
    shell.write_text("#!/bin/sh\n")
    shell.chmod(shell.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setattr(screenshot_report, "INSTALLED", ())
    assert screenshot_report.find_browser() == str(shell)
    monkeypatch.setenv("PATH", os.devnull)
    assert screenshot_report.find_browser() is None


@pytest.mark.slow  # starts Chromium twice
def test_the_screenshot_captures_a_page_taller_than_6000_px(tmp_path: Path):
    need(screenshot_report.find_browser() is not None, "Chromium", "sudo apt-get install chromium")
    page = tmp_path / "page.html"
    page.write_text('<html><body style="margin:0"><div style="height:9000px;background:#f00"></div>'
                    '<div style="height:100px;background:#00f"></div></body></html>')
    shot = tmp_path / "shot.png"
    assert screenshot_report.screenshot(page, shot, width=400) == 9100
    image = mpimg.imread(shot)
    assert image.shape[:2] == (9100, 400)
    assert tuple(image[8990, 200, :3]) == (1.0, 0.0, 0.0) and tuple(image[9090, 200, :3]) == (0.0, 0.0, 1.0)


@cache
def every_figure() -> dict[str, Rendered]:
    """Each figure the toolkit draws, on small made-up data (the correlation map at 10 model columns, as the A/B plan's)."""
    rng = np.random.default_rng(3)
    columns = ["Pedestrians", "Direction[Parallel]", "Direction[ParallelCrossing]", "Controller[A]", "Pedestrians*Direction[Parallel]",
               "Pedestrians*Direction[ParallelCrossing]", "Pedestrians*Controller[A]", "Direction[Parallel]*Controller[A]",
               "Direction[ParallelCrossing]*Controller[A]", "Pedestrians^2"]
    correlations = np.corrcoef(rng.normal(size=(len(columns), 30)))
    path = np.column_stack([np.linspace(-5, 5, 50), np.zeros(50)])
    panels = [(f"{i + 1}. RUN{i:02d} | {'AB'[i % 2]}\n4 ped | score 3", "AB"[i % 2], path, [path[::-1] + [0, 1]]) for i in range(6)]
    fraction = (np.linspace(0, 1, 20), np.linspace(0.2, 0.9, 20))
    profiles = [("Pedestrians", [2.0, 4.0, 6.0], [0.5, 0.3, 0.5], ["2", "4", "6"]),
                ("Direction", [0, 1, 2], [0.4, 0.4, 0.5], ["Parallel", "Crossing", "ParallelCrossing"]),
                ("Controller", [0, 1], [0.3, 0.3], ["A", "B"]), ("Speed", list(np.linspace(0.5, 1.5, 9)), list(np.linspace(0.3, 0.6, 9)), [])]
    residuals = [(f"metric {k}", tuple(rng.normal(size=18)), tuple(rng.normal(size=18)), tuple([True] + [False] * 17)) for k in range(4)]
    return {
        "correlation_map": correlation_map_figure(columns, correlations, "ab: correlations of model columns"),
        "design_evaluation": design_evaluation_figure(fraction, profiles, "ab: design evaluation"),
        "scores": score_distribution_figure({"A": [1, 3, 10], "B": [0, 5, 9]}, {1: 10.0, 2: 30.0, 3: 60.0}, "Score distribution"),
        "trajectories": trajectories_figure(panels, {"A": "#1f77b4", "B": "#d62728"}, "arm"),
        "shares": shares_figure([(2, {"A": (0.8, 0.6, 0.9), "B": (0.6, 0.4, 0.8)}), (4, {"A": (0.7, 0.5, 0.9), "B": (0.5, 0.3, 0.7)})], None, "shares"),
        "min_distance": min_distance_figure([("A", 2, 0.8), ("A", 6, 0.52), ("B", 2, 0.49), ("B", 6, 0.5)], ["A", "B"], "gap", 0.5),
        "residuals": residuals_figure(residuals),
        "run": run_figure(logged_run(12), "run X: Pedestrians 6, Direction Parallel, Controller A; goal", (5.0, 0.0), (0.0, 0.0)),
    }


@pytest.mark.slow  # draws every figure once, about 5 s
@pytest.mark.parametrize("name", ["correlation_map", "design_evaluation", "scores", "trajectories", "shares", "min_distance", "residuals", "run"])
def test_no_figure_prints_text_smaller_than_the_body_text_on_a4(name):
    figure = every_figure()[name]
    assert figure.width_in <= PRINT_COLUMN_IN + 1e-6 and figure.smallest_font_pt >= BODY_TEXT_PT
    assert figure.printed_font_pt >= BODY_TEXT_PT
    width, _ = (n / 100 for n in reversed(size(figure.png(100))))
    assert width == pytest.approx(figure.width_in, abs=0.02)  # the saved PNG is as wide as the figure says


def test_a_wide_figure_with_small_text_is_caught():
    from matplotlib.figure import Figure

    wide = Figure(figsize=(12.6, 3.0))
    wide.add_subplot().set_title("title", fontsize=12)
    figure = Rendered(wide)
    assert figure.smallest_font_pt == 10.0  # the tick labels
    assert figure.printed_font_pt == pytest.approx(10.0 * PRINT_COLUMN_IN / figure.width_in) and figure.printed_font_pt < 6.5


def test_the_correlation_map_is_signed_and_writes_each_r_at_the_body_size():
    columns = ["a", "b", "c"]
    correlations = np.array([[1.0, -0.5, 0.08], [-0.5, 1.0, 0.0], [0.08, 0.0, 1.0]])
    axes = correlation_map_figure(columns, correlations, "map").figure.axes[0]
    image = axes.get_images()[0]
    assert image.get_clim() == (-1.0, 1.0)
    cells = {(round(t.get_position()[1]), round(t.get_position()[0])): t for t in axes.texts}
    assert cells[(0, 1)].get_text() == "-.50" and cells[(0, 2)].get_text() == ".08" and cells[(2, 2)].get_text() == "1"
    assert {t.get_fontsize() for t in axes.texts} == {BODY_TEXT_PT}
    many = correlation_map_figure([f"column {i}" for i in range(30)], np.eye(30), "map").figure.axes[0]
    assert len(many.texts) == 0  # cells too narrow for a readable number show colour only


@pytest.mark.slow  # shares every_figure's drawing
def test_min_distance_names_the_intimate_distance_in_the_legend_where_no_point_covers_it():
    figure = every_figure()["min_distance"].figure
    axes = figure.axes[0]
    assert [t.get_text() for t in axes.get_legend().get_texts()] == ["A", "B", "intimate distance 0.5 m"]
    assert len(axes.texts) == 0
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(figure).get_renderer()
    figure.draw(renderer)
    assert axes.get_legend().get_window_extent(renderer).y0 >= axes.get_window_extent(renderer).y1  # above the data


@pytest.mark.slow  # two figures of two panels laid out, about 4 s
def test_the_power_figure_names_only_what_it_draws_and_keeps_its_legend_off_the_data():
    from trials.power.figure import power_rendered
    from trials.power.summary import PlanPower, PowerEstimate

    def plans(campaigns: int) -> list[PlanPower]:
        estimate = PowerEstimate(20, 40, 0.35, 0.65)
        return [PlanPower(runs, "d-optimal", {}, {}, {"Pedestrians": estimate, "Controller": estimate}, {}, campaigns,
                          {"Pedestrians": estimate, "Controller": estimate} if campaigns else {}) for runs in (18, 36)]

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    for campaigns, title in ((0, "Power by term: model-based (lines)"), (4, "Power by term: model-based (lines), closed-loop (open squares)")):
        rendered = power_rendered(plans(campaigns), 0.8)
        figure = rendered.figure
        assert figure.get_suptitle() == title and rendered.printed_font_pt >= BODY_TEXT_PT
        renderer = FigureCanvasAgg(figure).get_renderer()
        figure.draw(renderer)
        axes = figure.axes[0]
        assert axes.get_legend().get_window_extent(renderer).y0 >= axes.get_window_extent(renderer).y1
