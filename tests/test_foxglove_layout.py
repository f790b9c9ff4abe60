"""The Foxglove layout shipped for run logs: built by foxglove-sdk's layout types, and naming only topics and
fields the run-log format has."""

from __future__ import annotations

import json
import re

from robot_logs import run_log as fmt
from tests.support.scripts import load_script

foxglove_layout = load_script("foxglove_layout")


def panels(content: dict) -> list[dict]:
    if content.get("type") == "panel":
        return [content]
    return [panel for item in content["items"] for panel in panels(item["content"])]


def test_the_shipped_layout_is_what_the_sdk_builds():
    assert fmt.LAYOUT.read_text(encoding="utf-8") == foxglove_layout.layout_text()


def test_the_layout_shows_the_scene_the_robots_fields_and_the_events():
    layout = json.loads(fmt.LAYOUT.read_text(encoding="utf-8"))
    assert layout["version"] == 1
    found = {panel["panelType"]: panel["config"] for panel in panels(layout["content"])}
    assert set(found) == {"ThreeDee", "Plot", "StateTransitions", "RawMessages"}
    assert found["ThreeDee"]["fixedFrame"] == fmt.FRAME and fmt.SCENE.name in found["ThreeDee"]["topics"]
    topics = {topic.name: topic.schema for topic in vars(fmt).values() if isinstance(topic, fmt.Topic)}
    assert set(found["ThreeDee"]["topics"]) <= set(topics)
    paths = [series["value"] for series in found["Plot"]["paths"] + found["StateTransitions"]["paths"]]
    assert paths == ["/robot/state.v", "/robot/state.v_cmd", "/robot/state.w", "/robot/state.w_cmd", "/events.event"]
    for path in paths:  # every plotted field is one the channel's schema declares
        topic, field = re.fullmatch(r"(/[\w/]+)\.(\w+)", path).groups()
        assert field in fmt.SCHEMAS[topics[topic]]["properties"], path
    assert found["RawMessages"]["topicPath"] == fmt.EVENTS.name
