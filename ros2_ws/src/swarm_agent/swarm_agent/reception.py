"""One radio frame heard by the brains of a process: authenticated, routed, consumed.

A transmission reaches every robot in range (thesis 3.1.2); a process that holds many
brains (the headless evaluator) hands it to all its receivers at once, and a node with
one brain hands it to that one (``AgentBrain.on_packet``). Both run this code: the frame
is opened by every receiver's own replay window in one call (``frame_auth.open_all``),
then routed by every receiving router in one call (``dsdv_receive.hear``: the frame's
checks and decoding once, each router's state after), and what the routers deliver is
consumed by each brain (alike payloads by all their brains at once).

What these layers ask of the receivers themselves (their keyrings' groups and replay
rows, their routers' addresses and kernel groups) is worked out once per set of brains
that hear together (``Receivers``): a transmission reaches its source's neighbours, who
stay the same from one link update to the next and mostly across them, so a process
holding many brains keeps a ``Receivers`` per set it has seen (``ReceiverSets``), and a
node keeps one for its brain.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from operator import attrgetter
from typing import TYPE_CHECKING

from swarm_agent.dsdv_receive import hear, RouterOutput, Takers, takers_of
from swarm_agent.frame_auth import auth_groups, open_all
from swarm_agent.packet import Packet

if TYPE_CHECKING:
    from swarm_agent.brain import AgentBrain

_AUTH, _ROUTER = attrgetter('auth'), attrgetter('router')   # per receiver, at C speed


class Receivers:
    """Brains (or anything with an ``auth`` and a ``router``: the mission's radio) that
    hear transmissions together (distinct), with what opening and routing
    ask of them worked out once: their keyrings' groups and replay rows
    (``frame_auth.auth_groups``) and their routers' ``dsdv_receive.Takers`` (at first use:
    floods do not need them). Valid while the brains keep their ``FrameAuth`` and router,
    which they hold for life."""

    __slots__ = ('brains', 'auths', 'routers', 'opening', '_takers')

    def __init__(self, brains: Sequence[AgentBrain]) -> None:
        self.brains = list(brains)
        self.auths = list(map(_AUTH, self.brains))
        self.routers = list(map(_ROUTER, self.brains))
        # None: unauthenticated brains among them (comparisons), each opens on its own.
        self.opening = None if None in self.auths else auth_groups(self.auths)
        self._takers: Takers | None = None

    def takers(self) -> Takers:
        if self._takers is None:
            self._takers = takers_of(self.routers)
        return self._takers


class ReceiverSets:
    """``Receivers`` by the addresses a transmission reached, built once per distinct set
    (``brain_of``: the brain at an address, None when it has none here). ``clear`` it
    when a brain comes or goes."""

    LIMIT = 4096    # sets kept; all dropped when full (a few link updates' worth)

    def __init__(self, brain_of: Callable[[int], AgentBrain | None]) -> None:
        self._brain_of = brain_of
        self._sets: dict[tuple[int, ...], Receivers | None] = {}

    def __call__(self, addresses: Sequence[int]) -> Receivers | None:
        """The receivers at ``addresses`` in this process; None when there are none."""
        key = tuple(addresses)
        found = self._sets.get(key, self)
        if found is self:
            if len(self._sets) >= self.LIMIT:
                self._sets.clear()
            brains = [b for b in map(self._brain_of, key) if b is not None]
            found = self._sets[key] = Receivers(brains) if brains else None
        return found

    def clear(self) -> None:
        self._sets.clear()


def receive(t: float, packet: Packet, brains: Receivers | Sequence[AgentBrain]) -> None:
    """``packet``, heard at ``t`` by each of ``brains`` (distinct brains; a ``Receivers``
    when the caller keeps one)."""
    heard = brains if brains.__class__ is Receivers else Receivers(brains)
    if heard.opening is None:   # unauthenticated brains (comparisons)
        frames = [packet if auth is None else auth.open(packet) for auth in heard.auths]
    else:
        frames = open_all(heard.auths, packet, heard.opening)
    first = frames[0]
    if first is not None and frames.count(first) == len(frames):   # (identity first)
        _route(t, first, heard.brains, heard)   # all opened it alike: the common case
        return
    opened: Packet | None = None
    group: list[AgentBrain] = []       # the receivers that opened it to ``opened``
    others: list[tuple[AgentBrain, Packet]] = []
    for brain, frame in zip(heard.brains, frames):
        if frame is None:
            continue                    # rejected, counted by its FrameAuth
        if opened is None:
            opened = frame
        if frame is opened:
            group.append(brain)
        else:   # opened under another keyring (or none): routed on its own
            others.append((brain, frame))
    if group:
        _route(t, opened, group)
    for brain, frame in others:
        _route(t, frame, (brain,))


def _route(t: float, frame: Packet, brains: Sequence[AgentBrain],
           heard: Receivers | None = None) -> None:
    """``frame`` routed by the routers of ``brains`` (all of ``heard``'s, when given)."""
    outs = (hear(t, frame, list(map(_ROUTER, brains))) if heard is None
            else hear(t, frame, heard.routers, heard.takers()))
    first = outs[0]
    if not first.packets and outs.count(first) == len(outs):   # (identity first)
        # One output for all (a heartbeat's, a dump's nothing): taken once by all.
        if first.delivered:
            brains[0].take_delivered(t, brains, first.delivered)
        return
    # A router output shared by several receivers (a heartbeat's) holds payloads alike
    # for all of them: consumed once for the run of brains that got it.
    shared: RouterOutput | None = None
    run: list[AgentBrain] = []
    for brain, out in zip(brains, outs):
        if out.packets:
            brain.take_routed(t, out.packets, out.delivered)
        elif out.delivered:
            if out is not shared:
                if run:
                    run[0].take_delivered(t, run, shared.delivered)
                shared, run = out, []
            run.append(brain)
    if run:
        run[0].take_delivered(t, run, shared.delivered)
