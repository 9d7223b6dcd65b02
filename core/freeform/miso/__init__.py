"""MISO connection planning: the fewest connection changes between two configurations
of MISO modules -- any number of pieces, cycles allowed -- under the robot's rules.

Multiple-In-degree Single-Out-degree (MISO) modules -- FreeBOT, SnailBot -- have one
connector each: a module makes at most one out-connection but may carry others
(``msrr.core.robot.MisoRules``). Luo and Lam (2023, "Auto-optimizing connection
planning method for chain-type modular self-reconfiguration robots", the planning the
FreeSN paper cites in section 2.1) pair the modules of two such configurations with a
polynomial heuristic (IM) and an exact search (TBB). This package implements that
problem from its statement; the code is our own.

* :mod:`.model` -- configurations as pointer arrays (pieces and cycles), the robot's
  rules (:class:`MisoLimits`: a cap on the connections a module carries, no docking
  onto one's child or in-tree), legal steps, both metrics, random instances;
* :mod:`.pairing` -- the heuristic pairing (alignment rounds, then swaps);
* :mod:`.exact` -- the exact pairing (an integer program, ``scipy.optimize.milp``) and
  brute-force references;
* :mod:`.order` -- the step order under the rules;
* :mod:`.places` -- among pairings of the fewest changes, the one whose pieces travel
  least, when the configurations carry places;
* :mod:`.planner` -- solutions and :class:`~msrr.core.plan.Plan` s, the registered
  planners ``miso`` and ``miso-exact``;
* :mod:`.im` -- a reimplementation of Luo and Lam's IM, the benchmark's yardstick.

**Metrics.** A *step* re-targets one connector (one action); *connection changes*
count connections broken plus made (a move of a connector counts 2, connecting or
freeing one 1). Both are exact properties of a plan; the planners minimise changes
(Luo and Lam's metric), then steps. A pairing fixes the changes of a direct plan,
``|E_I| + |E_F| - 2 kept``; releases added by the step order break only connections
the direct move breaks anyway, so the plan's changes equal the pairing's.
"""

from __future__ import annotations

from .exact import brute_force_changes, brute_force_steps, exact_pairing
from .im import im_pairing
from .model import (
    FREE,
    UNLIMITED,
    MisoLimits,
    MisoProblem,
    Step,
    canonical_form,
    changes,
    children_of,
    count_flows,
    cycles,
    depths,
    is_flow,
    kept,
    mismatches,
    pairing_score,
    pieces,
    pointer_form,
    random_cyclic,
    random_forest,
    random_miso_tree,
    rooted,
    step_changes,
    step_is_legal,
    targets,
)
from .order import Ride, RiderClash, order_steps
from .pairing import heuristic_pairing
from .places import (
    class_moves,
    closed_ways,
    fragments,
    goal_in_start_frame,
    heading_turn,
    hold,
    nearer_pairing,
    riding_ways,
    step_travel,
    travel,
)
from .planner import (
    Layout,
    MisoPlanner,
    MisoSolution,
    carries_places,
    miso_planners,
    plan_miso,
    solve_exact,
    solve_heuristic,
)

__all__ = [
    "FREE",
    "Layout",
    "MisoLimits",
    "MisoPlanner",
    "MisoProblem",
    "MisoSolution",
    "Ride",
    "RiderClash",
    "Step",
    "UNLIMITED",
    "brute_force_changes",
    "brute_force_steps",
    "canonical_form",
    "carries_places",
    "changes",
    "children_of",
    "class_moves",
    "closed_ways",
    "count_flows",
    "cycles",
    "depths",
    "exact_pairing",
    "fragments",
    "goal_in_start_frame",
    "heading_turn",
    "heuristic_pairing",
    "hold",
    "im_pairing",
    "is_flow",
    "kept",
    "miso_planners",
    "mismatches",
    "nearer_pairing",
    "order_steps",
    "pairing_score",
    "pieces",
    "plan_miso",
    "pointer_form",
    "random_cyclic",
    "random_forest",
    "random_miso_tree",
    "riding_ways",
    "rooted",
    "solve_exact",
    "solve_heuristic",
    "step_changes",
    "step_is_legal",
    "step_travel",
    "targets",
    "travel",
]
