"""Everything the studio's Rerun recordings share: application id, timelines, entity paths.

One definition of each, used by every ``log_<kind>`` module of this package (dataset, evaluation),
so recordings of one dataset line up and merge in the viewer.
"""

from __future__ import annotations

__all__ = [
    "APPLICATION_ID",
    "TIMELINE_NODE",
    "TIMELINE_TIME",
    "WORLD",
    "PATH_GROUND_TRUTH",
    "PATH_INITIAL",
    "POSE_GROUND_TRUTH",
    "POSE_INITIAL",
    "LOOP_CLOSURES_INTRA",
    "LOOP_CLOSURES_INTER",
    "LOOP_CLOSURES_OUTLIERS",
    "INTER_LOOP_CLOSURE_DENSITY",
    "SIGHTINGS",
    "METRICS",
    "SERIES_POSITION_ERROR",
    "SERIES_LOOP_CLOSURES",
    "SERIES_INTER_LOOP_CLOSURES",
    "PROPERTY_DATASET",
    "PROPERTY_CONFIG",
    "EVALUATION",
    "EVALUATION_SUMMARY",
    "EVALUATION_SERIES",
    "EVALUATION_WORLD",
    "EVALUATION_GROUND_TRUTH",
    "EVALUATION_ESTIMATE",
    "TIMELINE_ITERATION",
    "SOLVE",
    "SOLVE_ESTIMATE",
    "SOLVE_GROUND_TRUTH",
    "SOLVE_CHI2",
    "SOLVE_ERROR",
    "SOLVE_SCALE",
    "TIMELINE_CELL",
    "SWEEP_TABLE",
    "SWEEP_SERIES",
    "TIMELINE_REPLAY",
    "TIMELINE_REPLAY_TICK",
    "REPLAY",
    "REPLAY_WORLD",
    "REPLAY_ESTIMATE",
    "REPLAY_GROUND_TRUTH",
    "REPLAY_LINKS",
    "REPLAY_CLOSURES",
    "REPLAY_APE",
    "REPLAY_SVE",
    "REPLAY_IN_CONTACT",
    "REPLAY_DELIVERED",
]

#: Fixed application id of every recording the studio writes, so recordings of one dataset (its
#: graph, an evaluation, a solve) saved with the same recording id merge in the viewer.
APPLICATION_ID = "cslam-studio"

# Timelines ----------------------------------------------------------------------------------------
#: Sequence timeline: the node (pose) index of each agent.
TIMELINE_NODE = "node"
#: Timestamp timeline, only when the data has real timestamps (not node index in seconds).
TIMELINE_TIME = "time"

# Entity paths -------------------------------------------------------------------------------------
WORLD = "world"
#: Static line strip: the whole ground-truth path of an agent.
PATH_GROUND_TRUTH = "world/{agent}/ground_truth"
#: Static line strip: the whole initial-estimate (dead-reckoning) path of an agent.
PATH_INITIAL = "world/{agent}/initial"
#: Transform moving along the timelines, with axes: the agent's current ground-truth pose.
POSE_GROUND_TRUTH = "world/{agent}/ground_truth_pose"
#: Transform moving along the timelines: the agent's current initial-estimate pose.
POSE_INITIAL = "world/{agent}/initial_pose"
#: One segment per intra-agent loop closure (inliers), at the node where it is created.
LOOP_CLOSURES_INTRA = "world/{agent}/loop_closures"
#: One segment per inter-agent loop closure (inliers) between two agents, at the node where it is
#: created; one entity per agent pair (``{pair}`` is ``<agent a>-<agent b>``, in agent order).
LOOP_CLOSURES_INTER = "world/inter_loop_closures/{pair}"
#: Many inter-agent loop closures (paper scale): one disc per cell of a grid over the map where
#: closures are, its size growing with how many fall there (where the agents' paths meet), logged at
#: the last node; drawn instead of the segments, which stay in their own entities, hidden.
INTER_LOOP_CLOSURE_DENSITY = "world/inter_loop_closure_density"
#: One segment per loop closure listed in the dataset's ``outliers.txt`` (intra- and inter-agent).
LOOP_CLOSURES_OUTLIERS = "world/outlier_loop_closures"
#: One segment per range-bearing sighting made by an agent (``range_bearing.txt``): from its
#: keyframe's reference pose to the point the range and bearing give, at the sighting's node and stamp.
SIGHTINGS = "world/{agent}/sightings"
METRICS = "metrics"
#: Scalar per node: |initial - ground truth| position [m].
SERIES_POSITION_ERROR = "metrics/position_error/{agent}"
#: Scalar per node: intra-agent loop closures created so far (one plot for all agents).
SERIES_LOOP_CLOSURES = "metrics/intra_loop_closures/{agent}"
#: Scalar per node: inter-agent loop closures created so far, all agents (a plot of its own: its
#: count is often ten times an agent's intra-agent count).
SERIES_INTER_LOOP_CLOSURES = "metrics/inter_loop_closures/all_agents"
#: Recording property holding the dataset facts.
PROPERTY_DATASET = "dataset"
#: Recording property holding the config that made the dataset (JSON text), when known.
PROPERTY_CONFIG = "config"

# Evaluation -----------------------------------------------------------------------------------------
EVALUATION = "evaluation"
#: Static Markdown table of an evaluation's statistics.
EVALUATION_SUMMARY = "evaluation/summary"
#: Scalar per node of one agent: ``{metric}`` is e.g. ``ape_translation_m`` (one plot per metric).
EVALUATION_SERIES = "evaluation/{metric}/{agent}"
#: Root of the 3D view of an evaluation.
EVALUATION_WORLD = "evaluation/world"
#: Static line strip: an agent's ground truth at the scored poses.
EVALUATION_GROUND_TRUTH = "evaluation/world/{agent}/ground_truth"
#: Static segments: an agent's (aligned) estimate, each segment coloured by its APE translation.
EVALUATION_ESTIMATE = "evaluation/world/{agent}/estimate"

# Solve ------------------------------------------------------------------------------------------------
#: Sequence timeline of an optimizer run: 0 is the initial guess, k the estimate after iteration k.
TIMELINE_ITERATION = "iteration"
SOLVE = "solve"
#: Points (coloured by their error against the ground truth) and path of an agent's estimate, per iteration.
SOLVE_ESTIMATE = "solve/{agent}/estimate"
#: Static path of an agent's ground truth, beside the estimate.
SOLVE_GROUND_TRUTH = "solve/{agent}/ground_truth"
#: Scalar per iteration: the graph's chi2 (g2o convention).
SOLVE_CHI2 = "solve/metrics/chi2"
#: Scalar per iteration: mean position error of the estimate against the ground truth [m].
SOLVE_ERROR = "solve/metrics/position_error_m"
#: Static text: what the estimate's point colours mean (the error scale and its range in metres).
SOLVE_SCALE = "solve/colour_scale"

# Sweep ------------------------------------------------------------------------------------------------
#: Sequence timeline of a sweep: the cell's position in the sweep's table.
TIMELINE_CELL = "cell"
#: Static Markdown table of the sweep.
SWEEP_TABLE = "sweep/table"
#: Scalar per cell of one numeric column (``{metric}``: the column's name).
SWEEP_SERIES = "sweep/{metric}"

# Replay -----------------------------------------------------------------------------------------------
#: Duration timeline of a replay: seconds since its start (the robots' clock).
TIMELINE_REPLAY = "replay_time"
#: Sequence timeline of a replay: the tick index (kollagen's data: the pose index).
TIMELINE_REPLAY_TICK = "tick"
REPLAY = "replay"
#: Root of the 3D view of a replay.
REPLAY_WORLD = "replay/world"
#: Line strip per checkpoint: what a robot believes of its own trajectory so far, per back-end.
REPLAY_ESTIMATE = "replay/world/{backend}/{agent}"
#: Static line strip: an agent's whole ground truth.
REPLAY_GROUND_TRUTH = "replay/world/ground_truth/{agent}"
#: Segments per checkpoint between the ground-truth positions of robots in contact.
REPLAY_LINKS = "replay/world/links"
#: Segments per checkpoint: the inter-agent closures delivered so far (ground-truth ends, decimated).
REPLAY_CLOSURES = "replay/world/delivered_closures"
#: Scalar per checkpoint: the team's APE (se3) of a back-end [m].
REPLAY_APE = "replay/metrics/ape_se3_m/{backend}"
#: Scalar per checkpoint: jrl's Shared Variable Error, translation [m], of a back-end whose robots
#: keep each other's poses (swarm, dgs), once some pose is shared.
REPLAY_SVE = "replay/metrics/sve_t_m/{backend}"
#: Scalar per tick: robots with at least one neighbour.
REPLAY_IN_CONTACT = "replay/metrics/robots_in_contact"
#: Scalar per tick: inter-agent closures delivered so far.
REPLAY_DELIVERED = "replay/metrics/closures_delivered"
