"""Build the Foxglove layout shipped for run logs (robot_logs/run_log_layout.json) with foxglove-sdk's layout types.

    python scripts/foxglove_layout.py            # rewrite the shipped file
    python scripts/foxglove_layout.py --check    # exit 1 if the shipped file differs from what this builds

Three panels over a run's MCAP: the 3-D scene from above, following the robot; the robot's velocity and
commanded velocity in a plot; the run's events on a state-transitions strip and as raw messages.
"""

from __future__ import annotations

import argparse
import json
import sys

import foxglove.layouts as fl

from robot_logs import run_log as fmt


def run_log_layout() -> dict:
    """The layout as JSON-able data (Foxglove's layout format, version 1)."""
    state = fmt.ROBOT_STATE.name
    scene = fl.ThreeDeePanel(
        title="scene",
        config=fl.ThreeDeeConfig(
            follow_tf="base_link", follow_mode="follow-position", fixed_frame=fmt.FRAME,
            topics={
                fmt.SCENE.name: fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                fmt.PLAN_POSES.name: fl.BaseRendererPosesTopicSettings(visible=True, type="line", line_width=0.05),
                fmt.RECORDED_POSES.name: fl.BaseRendererPosesTopicSettings(visible=True, type="line", line_width=0.03),
            },
        ),
    )
    velocity = fl.PlotPanel(
        title="robot velocity",
        config=fl.PlotConfig(
            paths=[fl.PlotSeries(value=f"{state}.{field}", label=label, timestamp_method="receiveTime")
                   for field, label in (("v", "v (m/s)"), ("v_cmd", "commanded v (m/s)"), ("w", "w (rad/s)"), ("w_cmd", "commanded w (rad/s)"))],
            show_legend=True, legend_display="top", x_axis_val="timestamp",
        ),
    )
    events = fl.StateTransitionsPanel(
        title="events",
        config=fl.StateTransitionsConfig(paths=[fl.StateTransitionsSeries(value=f"{fmt.EVENTS.name}.event", label="event",
                                                                          timestamp_method="receiveTime")]),
    )
    raw_events = fl.RawMessagesPanel(title="event detail", config=fl.RawMessagesConfig(topic_path=fmt.EVENTS.name, default_expanded=True))
    right = fl.SplitContainer(direction="column", items=[fl.SplitItem(proportion=2, content=velocity),
                                                         fl.SplitItem(proportion=1, content=events),
                                                         fl.SplitItem(proportion=1, content=raw_events)])
    layout = fl.Layout(content=fl.SplitContainer(direction="row", items=[fl.SplitItem(proportion=3, content=scene),
                                                                         fl.SplitItem(proportion=2, content=right)]))
    return json.loads(layout.to_json())


def layout_text() -> str:
    """The shipped file's text: the layout indented, keys in a stable order."""
    return json.dumps(run_log_layout(), indent=2, sort_keys=True) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with the shipped file instead of writing it")
    args = parser.parse_args()
    text = layout_text()
    if args.check:
        if fmt.LAYOUT.read_text(encoding="utf-8") != text:
            print(f"{fmt.LAYOUT} differs from what scripts/foxglove_layout.py builds; run it to rewrite the file", file=sys.stderr)
            return 1
        return 0
    fmt.LAYOUT.write_text(text, encoding="utf-8")
    print(f"Wrote {fmt.LAYOUT}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
