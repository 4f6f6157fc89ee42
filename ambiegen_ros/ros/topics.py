"""Topic names, message types and QoS of an AmbieGen run, in one place.

Every topic lives under ``/ambiegen``; the recorder records all of them (plus anything else it
discovers under the namespace). Scenario and result topics are reliable with a deep queue so a
burst of scenarios is never dropped; the run config is latched for late joiners. A scenario the
problem calls invalid is never sent: the generator logs it on ``not_sent(problem)``, a topic no
simulator reads, kept for a recorder that matches late (``NOT_SENT_QOS``).
"""
from __future__ import annotations

from .qos import DEFAULT, LATCHED, STREAM, Qos

NOT_SENT_QOS = Qos(reliable=True, transient_local=True, depth=100)
"""``not_sent`` topics: reliable, and the last 100 kept for a recorder that matches after the first ones."""

NAMESPACE = "/ambiegen"

RUN_CONFIG = f"{NAMESPACE}/run_config"
STATUS = f"{NAMESPACE}/status"
WORKERS = f"{NAMESPACE}/workers"
RESULTS = f"{NAMESPACE}/results"

# a hosted robot world's unmapped obstacles and people (issue 48): the adapter tells the world what
# is in it besides the map (std_msgs/String, JSON: {"stamp_ns", "obstacles"}); the world shows them
WORLD_OBSTACLES = f"{NAMESPACE}/world/obstacles"
WORLD_MARKERS = f"{NAMESPACE}/world/markers"

# what happened to the processes of a run, from whoever started them (``ambiegen rerun``): a
# stamped status per event, ERROR, name = the process, message = what (killed by SIGKILL, hung),
# hardware_id = "stack" (the system under test's) or "ours" (world, adapter, recorder). The adapter
# turns one during a run into FAIL(sut_crashed) or an error record; the recorder logs them all.
STACK_EVENTS = f"{NAMESPACE}/stack_events"
STACK_EVENTS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"

# a recorder's readiness, latched (one per recorder): level OK once every topic it was told to
# record (``extra_topics``) has a publisher and a matched reader (values: state = ready), WARN when
# its wait ran out first (values: missing = those topics), before that state = waiting. The
# generator sends no scenario before its recorders say ready (``min_recorders``)
RECORDER_STATUS = f"{NAMESPACE}/recorder_status"
RECORDER_STATUS_TYPE = "diagnostic_msgs/msg/DiagnosticStatus"

RUN_CONFIG_TYPE = "ambiegen_msgs/msg/RunConfig"
STATUS_TYPE = "ambiegen_msgs/msg/RunStatus"
WORKERS_TYPE = "diagnostic_msgs/msg/DiagnosticStatus"
RESULT_TYPE = "ambiegen_msgs/msg/ScenarioResult"

SCENARIO_TYPES = {
    "thermostat": "ambiegen_msgs/msg/ThermostatScenario",
    "robot": "ambiegen_msgs/msg/RobotScenario",
    "vehicle": "ambiegen_msgs/msg/VehicleScenario",
}


TIMELINE_TYPES = {
    "thermostat": "sensor_msgs/msg/Temperature",
    "robot": "nav_msgs/msg/Odometry",
    "vehicle": "nav_msgs/msg/Odometry",
}


def timeline(problem: str) -> str:
    """Where full-model sims stream what happened: robot/car odometry, room temperature."""
    return f"{NAMESPACE}/{problem}/" + ("temperature" if problem == "thermostat" else "odom")


def scenarios(problem: str) -> str:
    """The scenario topic of one problem, e.g. ``/ambiegen/robot/scenarios``."""
    return f"{NAMESPACE}/{problem}/scenarios"


def not_sent(problem: str) -> str:
    """Where the generator logs the scenarios it does not send because the problem calls them
    invalid, e.g. ``/ambiegen/vehicle/not_sent``: the scenario message (``meta.surrogate_valid``
    false, ``meta.invalid_reason`` the broken rule, ``meta.attempt`` 0); no simulator subscribes."""
    return f"{NAMESPACE}/{problem}/not_sent"


def run_topics() -> list[tuple[str, str, Qos]]:
    """(topic, type, QoS) of every topic an AmbieGen run may use, for every problem."""
    topics = [
        (RUN_CONFIG, RUN_CONFIG_TYPE, LATCHED),
        (STATUS, STATUS_TYPE, DEFAULT),
        (WORKERS, WORKERS_TYPE, DEFAULT),
        (RESULTS, RESULT_TYPE, STREAM),
        (STACK_EVENTS, STACK_EVENTS_TYPE, STREAM),
    ]
    topics += [(scenarios(p), t, STREAM) for p, t in SCENARIO_TYPES.items()]
    topics += [(not_sent(p), t, NOT_SENT_QOS) for p, t in SCENARIO_TYPES.items()]
    topics += [(timeline(p), t, STREAM) for p, t in TIMELINE_TYPES.items()]
    return topics
