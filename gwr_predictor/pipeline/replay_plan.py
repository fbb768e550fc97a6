"""What scripts/replay.sh plays from a bag, and where: topics, renames, the input node. No ROS here.

The person's input of a recorded run is one of
- `skeleton`: `<ns>/skeleton` (played into the replay's angle_extractor),
- `arm_angles`: `<ns>/arm_angles` (straight into the learner and the compensators),
- `hri`: a ROS4HRI tracker's body topics below /humans/bodies (played unchanged into hri_bodies),
where `<ns>` is the namespace the bag was recorded in (`run_pipeline.sh --namespace`). The replay runs in
its own namespace (`replay.sh --namespace`, default the root), so a pipeline topic is renamed from the
recorded namespace to the replay's: `/robot1/skeleton` plays as `/robot2/skeleton`.

    python -m gwr_predictor.pipeline.replay_plan BAG [--topic T | --hri] [--namespace NS]

prints the plan as `key value` lines for the script (`input`, `topic`, `remap`, `body`); errors go
to stderr with exit code 2.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from gwr_predictor.data import hri_bodies
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.pipeline import bag_reader, conventions, namespaces
from gwr_predictor.pipeline.errors import PipelineError

INPUTS = (conventions.TOPIC_SKELETON, conventions.TOPIC_ANGLES)


@dataclass(frozen=True)
class ReplayPlan:
    """What to play: `topics` as recorded, `remaps` ('recorded:=played'), the input kind (skeleton,
    arm_angles or hri) and, for hri with one recorded body, its id (hri_bodies follows it at once)."""

    input: str
    topics: tuple[str, ...]
    remaps: tuple[str, ...] = ()
    body: str = ""

    def lines(self) -> list[str]:
        return ([f"input {self.input}"] + [f"topic {t}" for t in self.topics] + [f"remap {r}" for r in self.remaps]
                + ([f"body {self.body}"] if self.body else []))


def type_available(msgtype: str) -> bool:
    """The message package of `msgtype` is importable here (a player needs the type to publish it)."""
    return importlib.util.find_spec(msgtype.partition("/")[0]) is not None


def pipeline_input(recorded: Sequence[str], topic: str | None, namespace: str, where: object) -> ReplayPlan:
    """The skeleton or angles topic to play (`topic`, else the bag's only `<ns>/skeleton`), renamed into the
    replay's `namespace`."""
    if topic is None:
        found = [t for t in recorded if namespaces.split_topic(t, conventions.TOPIC_SKELETON) is not None]
        if len(found) != 1:
            kind = "no" if not found else f"{len(found)}"
            raise PipelineError(f"{where}: {kind} skeleton topics with messages ({', '.join(found) or 'none'}): "
                                "choose one with --topic (e.g. /robot1/skeleton or /robot1/arm_angles)")
        topic = found[0]
    base = topic.rstrip("/").rsplit("/", 1)[-1]
    if base not in INPUTS or namespaces.split_topic(topic, base) is None:
        raise PipelineError(f"--topic {topic}: the person's input is a topic named skeleton or arm_angles, e.g. "
                            "/skeleton or /robot1/arm_angles")
    if topic not in recorded:
        raise PipelineError(f"{where}: no messages on {topic} (it has messages on {', '.join(recorded)})")
    played = namespaces.in_pipeline(namespace, base)
    return ReplayPlan(base, (topic,), (f"{topic}:={played}",) if played != topic else ())


def hri_input(info: bag_reader.BagInfo, available: Callable[[str], bool] = type_available,
              bodies_namespace: str = hri_bodies.BODIES_NAMESPACE) -> ReplayPlan:
    """Every recorded topic below the bodies namespace whose type this machine has (hri_msgs' IdsList
    only where hri_msgs is installed), unchanged: REP-155 topics are absolute."""
    prefix = bodies_namespace.rstrip("/") + "/"
    below = {t: msgtype for t, (msgtype, n) in info.topics.items() if n and t.startswith(prefix)}
    topics = tuple(sorted(t for t, msgtype in below.items() if available(msgtype)))
    bodies = hri_bodies.ids_from_topics(topics, bodies_namespace)
    if not bodies:
        raise PipelineError(f"{info.path}: no body joint states below {bodies_namespace} (record them with "
                            "scripts/record.sh --hri)")
    if len(bodies) == 1:  # one person: follow them at once, play only what hri_bodies then reads
        body = bodies[0]
        return ReplayPlan("hri", (hri_bodies.body_topic(bodies_namespace, body, hri_bodies.JOINT_STATES_TOPIC),),
                          body=body)
    return ReplayPlan("hri", topics)


def replay_plan(bag: str, topic: str | None = None, hri: bool = False, namespace: str = "") -> ReplayPlan:
    """The plan for `bag` (see the module docstring). Raises PipelineError / PipelineError (`bag_messages`)."""
    info = bag_reader.bag_info(bag)
    if hri:
        return hri_input(info)
    recorded = sorted(t for t, (_, n) in info.topics.items() if n)
    return pipeline_input(recorded, topic, namespaces.normalise(namespace), bag)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gwr_predictor.pipeline.replay_plan",
                                     description="what scripts/replay.sh plays from a bag")
    parser.add_argument("bag")
    parser.add_argument("--topic", default=None)
    parser.add_argument("--hri", action="store_true")
    parser.add_argument("--namespace", default="")
    args = parser.parse_args(argv)
    try:
        plan = replay_plan(args.bag, args.topic, args.hri, args.namespace)
    except GwrPredictorError as exc:
        print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    print("\n".join(plan.lines()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
