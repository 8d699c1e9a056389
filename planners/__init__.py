"""Motion planning for the agents: simulator-free and map-free (inputs are numpy arrays).

* :mod:`planners.occupancy` - 2-D occupancy grid from a 3-D point cloud, inflation, goal choice.
* :mod:`planners.raycast` - exact grid traversal of segments (the motion check).
* :mod:`planners.ompl_2d` - collision-free paths for a round base with OMPL.
* :mod:`planners.joint_space` - joint-space arm paths with OMPL and a pluggable validity test.
* :mod:`planners.tracking` - pure-pursuit path following (unicycle commands).
* :mod:`planners.replan` - is the path ahead blocked now?
* :mod:`planners.geodesic` - shortest 8-connected path lengths over a grid of free cells.
* :mod:`planners.push` - push geometry for "push X to the right of the line".
* :mod:`planners.result` - :class:`PlanResult`, the typed outcome of every planning query.

OMPL is imported only when a plan is requested.

May import: :mod:`conceptfusion`'s base modules (errors, names) only; no simulator, map or agent.
"""

from planners.errors import DegenerateGeometryError, PlannerError, UnknownPlannerError
from planners.geodesic import geodesic_field, geodesic_to_goal
from planners.joint_space import plan_joint_path
from planners.occupancy import GridConfig, OccupancyGrid, build_occupancy_grid, reachable_goal_near
from planners.ompl_2d import PLANNERS, BasePlannerConfig, plan_base_path
from planners.push import PushPlan, plan_push
from planners.replan import BlockedCheck, check_path_blocked
from planners.result import PLAN_STATUSES, PlanResult
from planners.tracking import PurePursuitConfig, TrackingState, pure_pursuit_step

__all__ = [
    "PlannerError",
    "UnknownPlannerError",
    "DegenerateGeometryError",
    "GridConfig",
    "OccupancyGrid",
    "build_occupancy_grid",
    "reachable_goal_near",
    "PLANNERS",
    "BasePlannerConfig",
    "plan_base_path",
    "plan_joint_path",
    "PurePursuitConfig",
    "TrackingState",
    "pure_pursuit_step",
    "BlockedCheck",
    "check_path_blocked",
    "PushPlan",
    "plan_push",
    "geodesic_field",
    "geodesic_to_goal",
    "PlanResult",
    "PLAN_STATUSES",
]
