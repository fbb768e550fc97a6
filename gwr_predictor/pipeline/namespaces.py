"""Which pipeline of a bag to read: a run of `run_pipeline.sh --namespace robot1` records its topics as
`/robot1/arm_angles`, `/robot1/uncompensated/joint_states`, ... (the recorder resolves relative names in
its namespace), while `/diagnostics` is global and may hold other pipelines' nodes of the same domain.

A pipeline is named by its namespace ("" for the root): the prefix of its `skeleton`, `arm_angles` or
`predictions` topic. The readers (report, latency, video, replay) take the bag's only pipeline, or the
one the user names when a bag holds several. Pure Python, no ROS.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.errors import PipelineError

#: The topics that make a namespace a pipeline's: the person's input and the learner's output.
PIPELINE_TOPICS = (conventions.TOPIC_SKELETON, conventions.TOPIC_ANGLES, conventions.TOPIC_PREDICTIONS)
_TOKENS = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")


def normalise(namespace: str) -> str:
    """'robot1', '/robot1/' -> '/robot1'; '' or '/' -> '' (the root). PipelineError for a name ROS would refuse."""
    stripped = namespace.strip().strip("/")
    if not stripped:
        return ""
    if not _TOKENS.fullmatch(stripped):
        raise PipelineError(f"namespace {namespace!r} is not a ROS namespace (tokens of letters, digits and _, "
                            "separated by /)")
    return "/" + stripped


def split_topic(topic: str, base: str) -> str | None:
    """The namespace of `topic` if its last name is `base` ('/robot1/arm_angles' -> '/robot1', '/arm_angles'
    -> ''), else None."""
    if topic == "/" + base:
        return ""
    if topic.endswith("/" + base) and topic.startswith("/"):
        return topic[: -len(base) - 1]
    return None


def within(namespace: str, pipeline: str) -> bool:
    """`namespace` is the pipeline's own or one below it (its `uncompensated` robot); the root pipeline
    takes every namespace."""
    return not pipeline or namespace == pipeline or namespace.startswith(pipeline + "/")


def in_pipeline(pipeline: str, name: str) -> str:
    """The absolute name of the pipeline's topic or node `name` ('/robot1' + 'arm_angles' -> '/robot1/arm_angles')."""
    return f"{pipeline}/{name}"


def pipelines_in(topics: Iterable[str]) -> list[str]:
    """Namespaces ("" = root) that have a pipeline topic among `topics`, sorted."""
    found = {ns for topic in topics for base in PIPELINE_TOPICS if (ns := split_topic(topic, base)) is not None}
    return sorted(found)


def describe(namespaces: Iterable[str]) -> str:
    return ", ".join(ns or "/" for ns in namespaces) or "none"


def choose_pipeline(topics: Iterable[str], requested: str | None, where: object) -> str:
    """The namespace of the pipeline to read among the topics with messages of the bag `where`: `requested`
    (normalised; PipelineError if the bag has no pipeline there), else the bag's only one ("" when it has
    none: the caller then says which topic is missing). Several and none requested: PipelineError listing them."""
    available = pipelines_in(topics)
    if requested is not None:
        namespace = normalise(requested)
        if namespace not in available:
            raise PipelineError(f"{where}: no pipeline in namespace {namespace or '/'} (pipelines recorded: "
                                f"{describe(available)})")
        return namespace
    if len(available) > 1:
        raise PipelineError(f"{where}: it holds the pipelines of {describe(available)}: choose one with --namespace")
    return available[0] if available else ""
