"""One radio frame heard by the brains of a process: authenticated, routed, consumed.

A transmission reaches every robot in range (thesis 3.1.2); a process that holds many
brains (the headless evaluator) hands it to all its receivers at once, and a node with
one brain hands it to that one (``AgentBrain.on_packet``). Both run this code: the frame
is opened by every receiver's own replay window in one call (``frame_auth.open_all``),
then routed by every receiving router in one call (``dsdv_receive.hear``: the frame's
checks and decoding once, each router's state after), and what the routers deliver is
consumed by each brain (alike payloads by all their brains at once).
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import attrgetter
from typing import TYPE_CHECKING

from swarm_agent.dsdv_receive import hear, RouterOutput
from swarm_agent.frame_auth import open_all
from swarm_agent.packet import Packet

if TYPE_CHECKING:
    from swarm_agent.brain import AgentBrain

_AUTH, _ROUTER = attrgetter('auth'), attrgetter('router')   # per receiver, at C speed


def receive(t: float, packet: Packet, brains: Sequence[AgentBrain]) -> None:
    """``packet``, heard at ``t`` by each of ``brains`` (distinct brains)."""
    auths = list(map(_AUTH, brains))
    if None in auths:   # unauthenticated brains (comparisons)
        frames = [packet if auth is None else auth.open(packet) for auth in auths]
    else:
        frames = open_all(auths, packet)
    first = frames[0]
    if first is not None and frames.count(first) == len(frames):   # (identity first)
        _route(t, first, brains)       # every receiver opened it alike: the common case
        return
    opened: Packet | None = None
    group: list[AgentBrain] = []       # the receivers that opened it to ``opened``
    others: list[tuple[AgentBrain, Packet]] = []
    for brain, frame in zip(brains, frames):
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


def _route(t: float, frame: Packet, brains: Sequence[AgentBrain]) -> None:
    outs = hear(t, frame, list(map(_ROUTER, brains)))
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
