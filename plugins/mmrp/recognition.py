"""Distributed configuration recognition (paper section 3.2, Fig. 4).

Every module is an agent that knows only its own id and which of its own faces are
connected; it talks only to the module across a connected face. The protocol:

1. every agent counts its connected faces; one face makes it a leaf; all connected
   faces switch to *receiving mode*;
2. a randomly chosen non-leaf agent starts: it sends ``(its id, the sending face)``
   on every connected face;
3. an agent that receives this on face F learns its parent connection
   ``connect(pF_p, self F)`` and sends its own id on its other faces (the search
   levels of Table 1); a second such message on another face means a closed loop,
   and that connection is recorded as a virtual one;
4. an agent with n connected faces whose n - 1 other faces have reported switches
   the remaining face to *sending mode* and reports the connections it collected;
   leaves report as soon as they are reached. When the starter has heard from every
   face, all leaves have been reached and the recognition has converged.

The host only collects what the starter uploads. A seeded scheduler delays and
reorders messages; the recognized configuration does not depend on it. Rounds count
the longest causal chain of messages (2 x the depth from the starter, O(|V|)).
"""

from __future__ import annotations

import heapq
from collections.abc import Mapping
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from msrr.core import Configuration
from msrr.core.errors import ConfigurationError

from .representation import Link, from_links, to_tree

__all__ = [
    "DistributedRecognizer",
    "Observation",
    "Recognition",
    "observe",
    "recognize_with_stats",
]

Observation = Mapping[str, Mapping[str, "tuple[str, str] | None"]]
"""Per module, per face: ``(other module, other face)`` if a link is physically made."""


@dataclass
class _Agent:
    """One module's local state: its id, its connected faces and what it learned."""

    id: str
    faces: tuple[str, ...]
    parent_face: str | None = None
    joined: bool = False
    done: set[str] = field(default_factory=set)
    collected: list[Link] = field(default_factory=list)
    loops: list[Link] = field(default_factory=list)

    @property
    def leaf(self) -> bool:
        return len(self.faces) == 1


@dataclass(frozen=True)
class Recognition:
    """The recognized configuration and the cost of recognizing it.

    Attributes:
        configuration: the tree, edges oriented away from the tree centre.
        virtual: loop connections turned into virtual ones (section 3.1).
        starter: the non-leaf module that started.
        leaves: the modules that detected themselves as leaves.
        rounds: longest causal chain of messages.
        messages: messages sent.
    """

    configuration: Configuration
    virtual: tuple[Link, ...]
    starter: str
    leaves: tuple[str, ...]
    rounds: int
    messages: int


def observe(config: Configuration) -> dict[str, dict[str, tuple[str, str] | None]]:
    """The observation a simulator would report for ``config``: every face's link or None."""
    from .representation import GRID_STEP, face_links

    links = face_links(config)
    return {v: {face: links[v].get(face) for face in GRID_STEP} for v in config.vertices()}


def _check(observation: Observation) -> None:
    for module, faces in observation.items():
        for face, link in faces.items():
            if link is None:
                continue
            other, other_face = link
            back = observation.get(other, {}).get(other_face)
            if back != (module, face):
                raise ConfigurationError(f"observation: face {face} of module {module} links "
                                         f"to {other}{other_face}, which does not link back")


class _Exchange:
    """The message exchange of steps 2-4 over the physical face links: a scheduler that
    delays every message by 1..``max_delay`` ticks and reorders ties at random.

    Attributes:
        sent: messages sent so far (also the scheduler's tie-break counter).
        rounds: longest causal chain of messages so far.
        finished: the starter has heard from every face.
    """

    def __init__(self, observation: Observation, agents: dict[str, _Agent],
                 rng: np.random.Generator, max_delay: int):
        self.observation = observation
        self.agents = agents
        self.rng = rng
        self.max_delay = max_delay
        self.queue: list[tuple[int, float, int, str, str, tuple]] = []
        self.sent = 0
        self.rounds = 0
        self.finished = False

    def send(self, sender: str, face: str, payload: tuple, depth: int, now: int) -> None:
        other, other_face = self.observation[sender][face]  # the physical channel
        self.sent += 1
        heapq.heappush(self.queue, (now + int(self.rng.integers(1, self.max_delay + 1)),
                                    float(self.rng.random()), self.sent, other, other_face,
                                    (*payload, depth)))

    def maybe_report(self, agent: _Agent, depth: int, now: int) -> None:
        """Step 4: report up the parent face once every other face has reported."""
        waiting = [f for f in agent.faces if f != agent.parent_face and f not in agent.done]
        if waiting:
            return
        if agent.parent_face is None:
            self.finished = True
            self.rounds = max(self.rounds, depth)
            return
        self.send(agent.id, agent.parent_face,
                  ("report", tuple(agent.collected), tuple(agent.loops)), depth + 1, now)

    def join(self, agent: _Agent, depth: int, now: int) -> None:
        """Steps 2-3: send this agent's id on every face but its parent's."""
        agent.joined = True
        for face in agent.faces:
            if face != agent.parent_face:
                self.send(agent.id, face, ("hello", agent.id, face), depth + 1, now)
        self.maybe_report(agent, depth, now)

    def receive(self, agent: _Agent, face: str, message: tuple, now: int) -> None:
        """A hello (a parent found, or a closed loop) or a report on ``face``."""
        kind, depth = message[0], message[-1]
        self.rounds = max(self.rounds, depth)
        if kind == "hello":
            sender, sender_face = message[1], message[2]
            if not agent.joined:
                agent.parent_face = face
                agent.collected.append((sender, sender_face, agent.id, face))
                self.join(agent, depth, now)
            else:  # a closed loop: both ends saw each other's hello
                agent.loops.append((sender, sender_face, agent.id, face))
                agent.done.add(face)
                self.maybe_report(agent, depth, now)
        else:
            agent.collected.extend(message[1])
            agent.loops.extend(message[2])
            agent.done.add(face)
            self.maybe_report(agent, depth, now)

    def run(self, starter: str) -> None:
        """From ``starter`` until it has heard from every face or no message is left."""
        self.join(self.agents[starter], 0, 0)
        if not self.agents[starter].faces:
            self.finished = True
        while self.queue and not self.finished:
            now, _, _, receiver, face, message = heapq.heappop(self.queue)
            self.receive(self.agents[receiver], face, message, now)


def _uploaded(agents: dict[str, _Agent], starter: str, finished: bool) -> Configuration:
    """The configuration the starter uploads: its collected links and each loop once.

    Raises:
        ConfigurationError: the exchange did not reach every module.
    """
    upload = agents[starter]
    reached = {upload.id} | {link[2] for link in upload.collected}
    if not finished or reached != set(agents):
        missing = sorted(set(agents) - reached)
        raise ConfigurationError(f"observation: modules {', '.join(missing)} are not connected "
                                 f"to {starter}")
    seen: set[frozenset] = set()
    loops = []
    for u, fu, v, fv in upload.loops:
        key = frozenset({(u, fu), (v, fv)})
        if key not in seen:
            seen.add(key)
            loops.append((u, fu, v, fv))
    return from_links(sorted(agents, key=_natural), [*upload.collected, *loops])


def recognize_with_stats(observation: Observation, *, seed: int = 0,
                         max_delay: int = 3) -> Recognition:
    """Run the distributed recognition over the face links of ``observation``.

    Args:
        observation: per module, per face, the module and face across it or None;
            used only as the message channel.
        seed: seeds the starter choice and the message delays.
        max_delay: each message takes 1..max_delay scheduler ticks, so messages are
            delayed and reordered.

    Raises:
        ConfigurationError: the observation is inconsistent or not connected.
    """
    _check(observation)
    rng = np.random.default_rng(seed)
    agents = {m: _Agent(str(m), tuple(sorted(f for f, link in faces.items() if link is not None)))
              for m, faces in observation.items()}
    if not agents:
        raise ConfigurationError("observation: no modules")
    leaves = tuple(m for m, a in agents.items() if a.leaf)
    candidates = sorted(m for m, a in agents.items() if len(a.faces) > 1) or sorted(agents)
    starter = candidates[int(rng.integers(len(candidates)))]
    exchange = _Exchange(observation, agents, rng, max_delay)
    exchange.run(starter)
    tree = to_tree(_uploaded(agents, starter, exchange.finished))
    return Recognition(_oriented(tree.tree), tree.virtual, starter, leaves, exchange.rounds,
                       exchange.sent)


def _natural(module: str) -> tuple[int, str]:
    return (int(module), module) if module.isdigit() else (1 << 62, module)


def _oriented(tree: Configuration) -> Configuration:
    """The same tree with every edge leading away from its centre (parent -> child)."""
    from .centre import adjacency, parents, root_of
    from .representation import face_links

    links = face_links(tree)
    parent = parents(adjacency(tree), root_of(tree))
    oriented = []
    for v, p in parent.items():
        if p is None:
            continue
        face = next(f for f, (w, _) in links[p].items() if w == v)
        oriented.append((p, face, v, links[p][face][1]))
    return from_links(tree.vertices(), oriented)


class DistributedRecognizer:
    """Configuration recognition by message passing between modules (section 3.2).

    The recognized configuration is a function of the links and the seed alone, and the
    links change only at a dock or an undock, so the last ``CACHE`` recognitions are
    kept by their links (the executor asks every tick: 20 % of a
    30-module run's time before).
    """

    name = "distributed"
    description = ("modules exchange ids over connected faces from a random non-leaf "
                   "starter until every leaf is reached (Wei et al. 2023, Fig. 4)")

    CACHE = 256

    def __init__(self) -> None:
        self._seen: dict[tuple, Configuration] = {}

    def recognize(self, observation: Observation, *, seed: int = 0) -> Configuration:
        """The configuration that ``observation`` shows; see :func:`recognize_with_stats`.
        Groups the reported links leave apart (after an undocking) recognize themselves
        each on its own, as separate systems do, and are joined."""
        key = (seed, tuple((m, tuple(sorted(faces.items()))) for m, faces
                           in sorted(observation.items())))
        found = self._seen.get(key)
        if found is None:
            groups = _groups(observation)
            if len(groups) == 1:
                found = recognize_with_stats(observation, seed=seed).configuration
            else:
                parts = [recognize_with_stats({m: observation[m] for m in sorted(g, key=_natural)},
                                              seed=seed).configuration for g in groups]
                found = Configuration.union(parts, robot=parts[0].robot)
            if len(self._seen) >= self.CACHE:
                del self._seen[next(iter(self._seen))]
            self._seen[key] = found
        return found.copy()


def _groups(observation: Observation) -> list[set[str]]:
    """The modules the reported face links connect, group by group (smallest id first)."""
    graph = nx.Graph()
    graph.add_nodes_from(observation)
    graph.add_edges_from((m, link[0]) for m, faces in observation.items()
                         for link in faces.values() if link is not None and link[0] in observation)
    return sorted((set(c) for c in nx.connected_components(graph)),
                  key=lambda g: min(g, key=_natural))
