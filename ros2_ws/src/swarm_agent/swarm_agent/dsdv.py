"""DSDV mesh routing of one agent (thesis 3.1.2, Figs. 3.5-3.9), driven by time arguments.

- Neighbour discovery: every heartbeat heard makes its sender a neighbour (route of one
  hop with the sender's own sequence number); a neighbour silent for
  ``neighbour_timeout_s`` is a broken link.
- Route table: destination -> (next hop, hops, destination sequence number), held as
  arrays shared by the routers of a process (``route_table``, where link addition and
  the selection rules are compiled kernels). Own sequence numbers are even and grow
  with every full dump; a broken link is advertised with an infinite metric and the
  odd sequence number one above the last known (3.1.2.3), so it overrides the stale
  route everywhere.
- Restarts: the first own number comes from the boot time (``boot_sequence``), so a
  restarted agent's numbers are newer than those of its previous run, which its
  neighbours still hold, without storing anything (condition in ``boot_sequence``).
- Selection rules: a route with a newer sequence number always wins; with the same
  sequence number the smaller hop count wins (3.1.2.1). Sequence numbers make stale
  routes lose, so there is no count-to-infinity. Damping (DSDV's settling concern):
  a newer number over a *longer* path from another neighbour is ignored unless the
  current route is broken or ``stale_generations`` full dumps old, so lost or late
  frames on the shortest path do not make routes flap. Ignoring an advert is the
  same as losing it, so loop freedom is kept.
- Periodic full dumps and triggered incremental updates of changed routes.
- Multi-hop delivery: routed unicast DATA hop by hop along next hops with a TTL, and
  FLOOD broadcasts deduplicated by (origin, flood id); messages longer than one frame
  are fragmented and reassembled.
- Flood relaying by the coverage condition of Wu and Dai on two-hop knowledge, with
  extra relays against loss (``flood_relay``).
- One frame, many receivers: ``hear`` (``dsdv_receive``) applies a frame to every
  router of a process that heard it, checking and decoding it once and updating the
  route tables of all of them in one call per store (the headless evaluator, the
  composed container); ``on_packet`` is the same for one.

Malformed, truncated or unknown frames are counted in ``stats`` and dropped.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import logging
import math

import numpy as np

from swarm_agent import flood_relay, wire
from swarm_agent.dsdv_receive import (
    Delivered,
    forget_neighbourhood,
    hear,
    RouterOutput,
    scalar_settings,
)
from swarm_agent.neighbour_table import NeighbourTable
from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_agent.route_table import (
    RouteEntry,
    RouteStore,
    RouteTable,
    SEQUENCE_MASK,
    SEQUENCE_STEP,
)
from swarm_agent.route_table import seq_newer as seq_newer  # this module's API as well
from swarm_agent.wire import INFINITE_HOPS as INFINITE_HOPS  # this module's API as well
from swarm_agent.wire import WireError
from swarm_common.parameters import tunable

LOG = logging.getLogger(__name__)
# The last message reassembled per (origin, kind, fragment key), shared (_reassemble).
_ASSEMBLED: dict[tuple[int, int, tuple[int, int, int]], Delivered] = {}
_ASSEMBLED_LIMIT = 1024
BOOT_RATE = 128  # boot_sequence grows by 2 * BOOT_RATE a second of boot time


def boot_sequence(boot_time_s: float) -> int:
    """The first own sequence number of a router booted at ``boot_time_s`` (s): even,
    ``2 * round(boot_time_s * BOOT_RATE)`` modulo 2**32 (as frame_auth's counter).

    A run's numbers grow by 2 a full dump (more when it outbids a broken advert, once per
    break). The restarted run's first number is newer than every number of the run before
    (serial order, ``seq_newer``) if (a) the clock did not step back across the restart,
    (b) the previous run grew its number by less than 2 * BOOT_RATE per second of its
    life (full dumps every 2 s grow it by 1; the config allows at most 100 a second), and
    (c) less than 2**30 / BOOT_RATE s (97 days) passed between the two boots.
    """
    return (2 * int(round(boot_time_s * BOOT_RATE))) & SEQUENCE_MASK


def _seq_add(a: int, n: int) -> int:
    return (a + n) & SEQUENCE_MASK


@dataclass
class DsdvConfig:
    """Timers of the router (seconds). The thesis runs its loop at 2 Hz."""
    heartbeat_period_s: float = tunable(0.5, 'Heartbeat period, s (3.1.2)', low=0.01, high=60.0)
    neighbour_timeout_s: float = tunable(2.0, 'Silence that ends a neighbour, s', low=0.01,
                                         high=600.0)
    full_dump_period_s: float = tunable(2.0, 'Full route dump period, s (3.1.2)', low=0.01,
                                        high=600.0)
    incremental_min_interval_s: float = tunable(
        0.25, 'Least interval between incremental route updates, s', low=0.0, high=60.0)
    default_ttl: int = tunable(32, 'Hops a packet may travel', low=1, high=255)
    dedup_memory: int = tunable(4096, 'Packets kept to drop duplicates', low=1, high=10**6)
    reassembly_timeout_s: float = tunable(5.0, 'An incomplete fragmented message is dropped '
                                          'after this long, s', low=0.01, high=600.0)
    stale_generations: int = tunable(6, 'Full dumps a shorter route may lag before a longer '
                                     'one wins', low=1, high=1000)
    flood_extra_copies: float = tunable(2.0, 'Least extra relays per neighbourhood (loss '
                                        'redundancy)', low=0.0, high=100.0)
    flood_miss_target: float = tunable(0.01, 'Wanted chance that one robot misses one flood '
                                       'hop', low=1e-6, high=1.0)
    loss_memory: float = tunable(0.95, 'Per-heartbeat decay of the link loss counts', low=0.0,
                                 high=1.0)


class DsdvRouter:
    """DSDV routing for one agent; see the module docstring."""

    def __init__(self, node_id: int, config: DsdvConfig | None = None,
                 boot_time_s: float = 0.0, store: RouteStore | None = None) -> None:
        """``store`` holds the route tables of the process's routers (``route_table``:
        a frame's receivers are updated in one call); None: a store of its own."""
        self.id = int(node_id)
        self.config = config or DsdvConfig()
        self.route_table = RouteTable(store, self.id)
        # Receivers of one frame holding this token share one kernel call (hear).
        self._group = self.route_table.store.group(scalar_settings(self.config))
        self._row = np.array([self.route_table.row], dtype=np.int64)   # its rows, alone
        self.sequence = boot_sequence(boot_time_s)
        # Neighbours heard, with their heartbeat counts: the store's, row for row.
        self.neighbour_table = NeighbourTable(self.route_table.store.neighbours,
                                              self.route_table.row)
        # neighbour -> its advertised neighbours (immutable: receivers of one dump that
        # knew the same set share what it becomes, dsdv_receive._learn_neighbourhood)
        self.two_hop: dict[int, frozenset[int]] = {}
        self._copies = self.config.flood_extra_copies  # k, renewed at every heartbeat sent
        # Flood relay decisions depend only on the two-hop view: kept until it changes.
        self._silent_after: dict[int, bool] = {}  # previous hop -> stay silent?
        self._view_masks: tuple[int, int] | None = None   # _should_relay's, per view
        self._view: set[int] | None = None        # the neighbours, kept until they change
        self._known_grew = False   # two_hop has a neighbour more than the view's masks saw
        self._info: bytes | Callable[[], bytes] = b''
        self._tx_seq = 0
        self._flood_id = 0
        self._frag_id = 0
        self._next_heartbeat = 0.0
        self._next_full = 0.0
        self._last_incremental = -1e9
        # tick() runs at 50 Hz but rarely has work: kept so it does not scan every call.
        self._next_expiry = math.inf
        self._dirty = False
        self._wake = 0.0   # earliest of the three timers above: before it, tick() is idle
        # The flood keys it handled, the store's (flood_memory): copies are dropped.
        self._floods = self.route_table.store.floods
        self._floods.memory[self.route_table.row] = self.config.dedup_memory
        self._partial: dict[tuple[int, int, int], tuple[float, dict[int, bytes]]] = {}
        self._stats: dict[str, int] = {}

    # ------------------------------------------------------------------ helpers
    def _count(self, key: str, n: int = 1) -> None:
        self._stats[key] = self._stats.get(key, 0) + n

    @property
    def stats(self) -> dict[str, int]:
        """Frames counted by what became of them (a copy), with the flood copies
        dropped as ``duplicates``."""
        duplicates = int(self._floods.duplicates[self.route_table.row])
        return {**self._stats, 'duplicates': duplicates} if duplicates else dict(self._stats)

    def _malformed(self, kind: Kind, source: int, exc: WireError) -> None:
        self._count('rejected_malformed')
        LOG.debug('agent %d dropped a %s frame from %d: %s', self.id, kind.name, source, exc)

    def _packet(self, destination: int, kind: int, payload: bytes,
                ttl: int | None = None) -> Packet:
        self._tx_seq = (self._tx_seq + 1) & 0xFFFF
        self._count('packets_sent')
        self._count('bytes_sent', len(payload))
        return Packet(self.id, destination, int(kind), self._tx_seq,
                      self.config.default_ttl if ttl is None else ttl, payload)

    def set_heartbeat_info(self, info: bytes | Callable[[], bytes]) -> None:
        """Small application blob carried by every heartbeat (at most 79 bytes: the
        frame body ``packet.MAX_BODY`` less the sequence number); a callable is asked
        for it only when a heartbeat goes out."""
        self._info = info if callable(info) else bytes(info)

    # ------------------------------------------------------------------ queries
    @property
    def sequence(self) -> int:
        """Own sequence number: even, grown at every full dump; held in the route store,
        where the selection rules outbid an advert of this router's broken routes."""
        return self.route_table.own_sequence

    @sequence.setter
    def sequence(self, sequence: int) -> None:
        self.route_table.own_sequence = sequence

    @property
    def table(self) -> dict[int, RouteEntry]:
        """The route table by destination, as copies (``set_route`` writes one)."""
        return {e.destination: e for e in self.route_table.entries()}

    def set_route(self, entry: RouteEntry) -> None:
        """Write one route (a fault study's forged table, a test's set-up)."""
        self.route_table.set(entry)

    def routes(self) -> list[RouteEntry]:
        """The route table, sorted by destination (own entry excluded; copies)."""
        return self.route_table.entries()

    @property
    def heard(self) -> dict[int, float]:
        """Neighbour -> when last heard, by address (a copy)."""
        return self.neighbour_table.heard()

    def neighbours(self) -> set[int]:
        """Direct neighbours currently heard (a copy)."""
        return set(self._neighbours())

    def _neighbours(self) -> set[int]:
        if self._view is None:
            self._view = self.neighbour_table.ids()
        return self._view

    def reachable(self) -> set[int]:
        """Destinations with a finite route."""
        return self.route_table.reachable()

    def next_hop(self, destination: int) -> int | None:
        return self.route_table.next_hop(destination)

    # ------------------------------------------------------------------ timers
    def idle(self, t: float) -> bool:
        """Whether ``tick(t)`` has nothing to do (no timer due, nothing changed)."""
        return t < self._wake and not self._dirty and not self._partial

    def tick(self, t: float) -> list[Packet]:
        """Heartbeats, neighbour timeouts, full dumps and triggered updates due at ``t``."""
        if self.idle(t):
            return []
        out: list[Packet] = []
        if t > self._next_expiry:
            gone, self._next_expiry = self.neighbour_table.silent(
                t, self.config.neighbour_timeout_s)
            for neighbour in gone:
                self._break_link(neighbour)
        if t >= self._next_heartbeat:
            self._next_heartbeat = t + self.config.heartbeat_period_s
            self._copies = self._extra_copies()
            info = self._info() if callable(self._info) else self._info
            out.append(self._packet(BROADCAST, Kind.HEARTBEAT,
                                    wire.encode_heartbeat(self.sequence, info), ttl=1))
        if t >= self._next_full:
            self._next_full = t + self.config.full_dump_period_s
            self.sequence = _seq_add(self.sequence, SEQUENCE_STEP)
            ids, hops, seqs = self.route_table.advert_columns()
            # Its own route first: itself at 0 hops with its new number.
            for frame in wire.encode_advert_columns(
                    self.sequence, np.concatenate(([self.id], ids)),
                    np.concatenate(([0], hops)), np.concatenate(([self.sequence], seqs))):
                out.append(self._packet(BROADCAST, Kind.DSDV_FULL, frame, ttl=1))
            self.route_table.clear_changed()
            self._dirty = False
            self._last_incremental = t
        elif (self._dirty
              and t - self._last_incremental >= self.config.incremental_min_interval_s
              and self.route_table.any_changed()):
            for frame in wire.encode_advert_columns(
                    self.sequence, *self.route_table.advert_columns(changed_only=True)):
                out.append(self._packet(BROADCAST, Kind.DSDV_INCREMENTAL, frame, ttl=1))
            self.route_table.clear_changed()
            self._dirty = False
            self._last_incremental = t
        for key, (started, _) in list(self._partial.items()):
            if t - started > self.config.reassembly_timeout_s:
                del self._partial[key]
                self._count('fragments_expired')
        self._wake = min(self._next_expiry, self._next_heartbeat, self._next_full)
        return out

    def _break_link(self, neighbour: int) -> None:
        """Fig. 3.9: every route through the neighbour gets hops = inf and an odd sequence."""
        self.neighbour_table.forget(neighbour)
        forget_neighbourhood(self, neighbour)
        self._view_changed()
        if self.route_table.break_link(neighbour):
            self._dirty = True
        self._count('link_breaks')

    # ------------------------------------------------------------------ receive
    def on_packet(self, t: float, packet: Packet) -> RouterOutput:
        """Handle one frame heard on the radio. The result is read-only (may be shared)."""
        return hear(t, packet, (self,))[0]

    def link_loss(self) -> float:
        """Share of the neighbours' heartbeats this node did not hear (recent, decayed)."""
        return self.neighbour_table.loss()

    def _extra_copies(self) -> float:
        """k of ``flood_relay`` for the loss seen now."""
        return flood_relay.extra_copies(self.config.flood_extra_copies, self.link_loss(),
                                        self.config.flood_miss_target)

    def _new_neighbour(self, t: float) -> None:
        """A neighbour heard for the first time since its link last broke (its time and
        counts are the neighbour table's, its one-hop route the route table's: both
        applied by ``hear`` to every receiver at once)."""
        self._view_changed()
        if self._next_expiry == math.inf:   # it is the only neighbour
            self._next_expiry = t + self.config.neighbour_timeout_s
            self._wake = min(self._wake, self._next_expiry)

    def _view_changed(self) -> None:
        self._silent_after.clear()
        self._view_masks = None
        self._view = None
        self._known_grew = False

    def _neighbourhood_changed(self, neighbour: int) -> None:
        """What this node knows of ``neighbour``'s neighbours changed, not its own
        neighbours. ``flood_relay.covered`` reads the previous hop's neighbourhood and
        those of higher-id neighbours only, so the change of a lower-id neighbour's
        renews the one decision after a flood from it; any other renews all."""
        if neighbour > self.id or self._known_grew:
            self._view_changed()
        else:
            self._silent_after.pop(neighbour, None)

    def _should_relay(self, previous_hop: int, origin: int, flood_id: int) -> bool:
        """Relay unless the coverage condition (``flood_relay``) lets this node be silent."""
        silent = self._silent_after.get(previous_hop)
        if silent is None:
            if self._view_masks is None:   # as masks: neighbours, those with a higher id
                view = self._neighbours()  # and a known neighbourhood
                self._view_masks = (flood_relay.mask(view), flood_relay.mask(
                    [z for z in view if z > self.id and z in self.two_hop]))
            silent = self._silent_after[previous_hop] = flood_relay.covered(
                previous_hop, self._view_masks[0], self.two_hop, self._view_masks[1])
        if not silent:
            return True
        return flood_relay.relays_anyway(self._copies, len(self._neighbours()), flood_id,
                                         origin, self.id)

    # ------------------------------------------------------------------ data plane
    def send(self, t: float, destination: int, payload: bytes) -> list[Packet]:
        """Routed unicast to ``destination`` (fragmented when longer than one frame)."""
        hop = self.next_hop(destination)
        if hop is None:
            self._count('no_route')
            return []
        self._frag_id = (self._frag_id + 1) & 0xFFFF
        return [self._packet(hop, Kind.DATA, wire.encode_routed(self.id, destination, chunk))
                for chunk in wire.split_message(bytes(payload), self._frag_id)]

    def broadcast(self, t: float, payload: bytes) -> list[Packet]:
        """Flood to the whole mesh, deduplicated by every receiver."""
        self._frag_id = (self._frag_id + 1) & 0xFFFF
        out = []
        for chunk in wire.split_message(bytes(payload), self._frag_id):
            self._flood_id = (self._flood_id + 1) & 0xFFFF
            self._remember((self.id, self._flood_id))
            out.append(self._packet(BROADCAST, Kind.FLOOD,
                                    wire.encode_routed(self.id, self._flood_id, chunk)))
        return out

    def _remember(self, key: tuple[int, int]) -> bool:
        """Record a flood id; False if it was already seen."""
        return self._floods.remember(self.route_table.row, key)

    def remembered(self) -> list[tuple[int, int]]:
        """The flood keys (origin, flood id) whose copies it drops, oldest first."""
        return self._floods.held(self.route_table.row)

    def _on_data(self, t: float, packet: Packet, out: RouterOutput) -> None:
        origin, final, chunk = wire.decode_routed(packet.payload)
        if final == self.id:
            self._deliver(t, origin, Kind.DATA, chunk, out)
            return
        if packet.ttl <= 1:
            self._count('dropped_ttl')
            return
        hop = self.next_hop(final)
        if hop is None:
            self._count('no_route')
            return
        self._count('forwarded')
        out.packets.append(self._packet(hop, Kind.DATA, packet.payload, ttl=packet.ttl - 1))

    def _relay(self, packet: Packet, origin: int, flood_id: int) -> list[Packet]:
        """A flood heard first: relayed unless its hops are spent or the coverage
        condition lets this node be silent."""
        if packet.ttl <= 1:
            self._count('dropped_ttl')
        elif not self._should_relay(packet.source, origin, flood_id):
            self._count('flood_pruned')
        else:
            self._count('forwarded')
            return [self._packet(BROADCAST, Kind.FLOOD, packet.payload, ttl=packet.ttl - 1)]
        return []

    def _deliver(self, t: float, origin: int, kind: int, chunk: bytes,
                 out: RouterOutput) -> None:
        message, frag = wire.parse_chunk(chunk)
        if frag is None:
            out.delivered.append(Delivered(origin, kind, message))
            self._count('delivered')
            return
        whole = self._reassemble(t, origin, kind, message, frag)
        if whole is not None:
            out.delivered.append(whole)

    def _reassemble(self, t: float, origin: int, kind: int, piece: bytes,
                    frag: tuple[int, int, int]) -> Delivered | None:
        """One fragment of a message; the message once all its fragments are in."""
        frag_id, index, count = frag
        key = (origin, frag_id, count)
        partial = self._partial.get(key)
        if partial is None:
            partial = self._partial[key] = (t, {})
        pieces = partial[1]
        pieces[index] = piece
        if len(pieces) < count:
            return None
        del self._partial[key]
        self._count('delivered')
        message = b''.join(pieces[i] for i in range(count))
        # The routers of a process that complete one message share one Delivered, whose
        # payload's decoding is then kept (wire.last_result): the same bytes, compared.
        kept = _ASSEMBLED.get((origin, kind, key))
        if kept is not None and kept.payload == message:
            return kept
        if len(_ASSEMBLED) >= _ASSEMBLED_LIMIT:
            _ASSEMBLED.clear()
        delivered = _ASSEMBLED[origin, kind, key] = Delivered(origin, kind, message)
        return delivered
