"""Authenticated radio frames: a truncated HMAC-SHA256 and a replay window per source.

Every frame a node of the mesh transmits ends with a 17-byte trailer inside its payload,
so it travels wherever the payload does (the simulated medium, RadioPacketArray over
ROS, the XBee RF payload): one wire format for every transport::

    payload = body | u8 key_id | u64 counter (little-endian) | tag[8]
    tag     = HMAC-SHA256(key[key_id],
                          u16 source | u16 destination | u8 kind | u16 sequence | u8 ttl
                          | body | key_id | counter)[:8]

- Link level, hop by hop: the tag covers the link header as the frame is on the air.
  A forwarding robot builds a new frame under its own address (``DsdvRouter._packet``:
  source = the forwarder, ttl - 1) and seals it with its own counter, so nothing the tag
  covers changes between transmitter and receiver. The origin of routed data stays in
  the body (``wire.encode_routed``) and is covered too.
- Key ids: a ``Keyring`` holds the keys accepted by id (0..255) and the id frames are
  sealed with; rotating is: add the new key everywhere, switch ``seal`` to it, remove
  the old one.
- Counter, per source: ``round(boot wall time * 2**20) + frames sealed since boot``,
  i.e. boot time in units of 2**-20 s (0.95 us) plus a frame count. A restarted process
  starts above every counter its previous run sent as long as (a) the wall clock did not
  step back across the restart and (b) the previous run sealed fewer than 2**20 (about
  a million) frames per second of its life on average: its last counter is below
  ``boot1 * 2**20 + life * 2**20 <= boot2 * 2**20``. An XBee at 250 kbit/s carries a few
  hundred frames a second. No state is stored.
- Replay window, per source at each receiver (RFC 4303 3.4.3, RFC 6347 4.1.2.6): the
  highest counter accepted and a 64-bit bitmap of the 64 counters below it. A counter
  above the highest moves the window; one inside it is accepted once; one below it is
  too old. The window moves only after the tag checks out, so forged frames cannot
  push it ahead of the real source.

Rejections are counted by kind in ``FrameAuth.stats``: ``auth_short`` (no room for a
trailer), ``auth_unknown_key``, ``auth_bad_tag``, ``auth_replay``, ``auth_too_old``.

Verifying is the same computation for every receiver of one transmission: the tag check
is cached per process on the frame's bytes (``_verified``: the same answer, computed once
when a composed process or the headless evaluator holds many receivers; a frame sealed
in the process is entered when it is sealed, its tag known good), and the last
frame object checked is remembered (``_Verifier``: receivers of one transmission get it in
a row); each receiver still applies its own replay window.

Why 8 bytes of tag: a forger's chance per attempt is 2**-64; at the few hundred frames a
second a radio carries that is beyond any attack time. 16 bytes would cost 8 more bytes
of the 100-byte XBee payload on every frame.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
import functools
import hmac
import pathlib
import secrets
import struct
import sys
import time

import numpy as np
import yaml

from swarm_agent.address_grid import AddressGrid
from swarm_agent.packet import Packet
from swarm_common.jit import kernel

TAG_BYTES = 8
_TRAILER = struct.Struct('<BQ')          # key id, counter (then the tag)
TRAILER_BYTES = _TRAILER.size + TAG_BYTES  # 17: the overhead of one frame
_LINK = struct.Struct('<HHBHB')           # source, destination, kind, sequence, ttl
WINDOW = 64                               # counters remembered below the highest
COUNTER_SCALE = 1 << 20                   # counter units per second of boot time
COUNTER_MASK = (1 << 64) - 1
MIN_KEY_BYTES = 16
REJECTIONS = ('auth_short', 'auth_unknown_key', 'auth_bad_tag', 'auth_replay',
              'auth_too_old')


class FrameAuthError(ValueError):
    """A key file or keyring that cannot be used."""


@dataclass(frozen=True)
class Keyring:
    """Swarm keys by id (all accepted) and the id new frames are sealed with."""

    keys: tuple[tuple[int, bytes], ...]
    seal_id: int
    development: bool = False   # the published development key: anyone can forge with it
    _by_id: Mapping[int, bytes] = field(init=False, repr=False, compare=False, hash=False)

    def __post_init__(self) -> None:
        by_id = dict(self.keys)
        if len(by_id) != len(self.keys):
            raise FrameAuthError('a key id appears twice in the keyring')
        for kid, key in by_id.items():
            if not 0 <= kid <= 255:
                raise FrameAuthError(f'key id {kid} is outside 0..255')
            if len(key) < MIN_KEY_BYTES:
                raise FrameAuthError(f'key {kid} has {len(key)} bytes; use at least '
                                     f'{MIN_KEY_BYTES} (32 random bytes recommended)')
        if self.seal_id not in by_id:
            raise FrameAuthError(f'seal key id {self.seal_id} is not among the keys '
                                 f'{sorted(by_id)}')
        object.__setattr__(self, '_by_id', by_id)

    def key(self, key_id: int) -> bytes | None:
        return self._by_id.get(key_id)


def new_key_file_text(key_id: int = 1) -> str:
    """A fresh key file (32 random bytes) for a deployment."""
    return ('# Swarm key: keep secret; every robot and the mission computer hold the same.\n'
            f'seal: {key_id}\nkeys:\n  {key_id}: {secrets.token_hex(32)}\n')


@functools.lru_cache(maxsize=16)
def load_keyring(path: str) -> Keyring:
    """Read a key file (YAML: ``seal: id``, ``keys: {id: hex}``, ``development: bool``).

    Raises FrameAuthError with one line naming the file and the fix.
    """
    fix = ('write one with `python -m swarm_agent.frame_auth > FILE` and pass it as '
           'swarm_key_file (evaluate: --swarm-key-file)')
    try:
        data = yaml.safe_load(pathlib.Path(path).read_text())
    except OSError as exc:
        raise FrameAuthError(f'cannot read swarm key file {path}: {exc.strerror}; {fix}') \
            from None
    except yaml.YAMLError:
        raise FrameAuthError(f'swarm key file {path} is not YAML; {fix}') from None
    if not isinstance(data, dict) or not isinstance(data.get('keys'), dict) or \
            not data['keys'] or 'seal' not in data:
        raise FrameAuthError(f'swarm key file {path} needs "seal: <id>" and "keys: '
                             f'{{<id>: <hex>}}"; {fix}')
    try:
        keys = tuple(sorted((int(k), bytes.fromhex(str(v))) for k, v in data['keys'].items()))
        return Keyring(keys, int(data['seal']), bool(data.get('development', False)))
    except (TypeError, ValueError) as exc:
        raise FrameAuthError(f'swarm key file {path}: {exc}; {fix}') from None


def boot_counter(boot_time_s: float) -> int:
    """The first counter of a process booted at ``boot_time_s`` (wall clock, s)."""
    return int(round(boot_time_s * COUNTER_SCALE)) & COUNTER_MASK


@functools.lru_cache(maxsize=64)
def _keyed(key: bytes) -> hmac.HMAC:
    """HMAC-SHA256 with ``key`` set up, to be copied per frame: 1.8 us a tag against 6.5
    for ``hmac.digest`` (which looks the digest up in OpenSSL 3 at every call)."""
    return hmac.new(key, digestmod='sha256')


def _tag(key: bytes, data: bytes) -> bytes:
    mac = _keyed(key).copy()
    mac.update(data)
    return mac.digest()[:TAG_BYTES]


_OPENED: OrderedDict[tuple, Packet | None] = OrderedDict()   # _verified's, oldest first
_OPENED_LIMIT = 8192
_UNKNOWN = object()


def _verified(key: bytes, source: int, destination: int, kind: int, sequence: int, ttl: int,
              payload: bytes) -> Packet | None:
    """The frame without its trailer if the tag matches (payload holds the trailer), else
    None. Kept (the last ``_OPENED_LIMIT``): every receiver of one transmission asks the
    same question, and gets the same read-only frame (whose payload object the decoders'
    caches then hash once); a frame sealed in this process is known good from its seal."""
    question = (key, source, destination, kind, sequence, ttl, payload)
    opened = _OPENED.get(question, _UNKNOWN)
    if opened is _UNKNOWN:
        tag = _tag(key, _LINK.pack(source, destination, kind, sequence, ttl)
                   + payload[:-TAG_BYTES])
        opened = (Packet(source, destination, kind, sequence, ttl, payload[:-TRAILER_BYTES])
                  if hmac.compare_digest(tag, payload[-TAG_BYTES:]) else None)
        _keep(question, opened)
    return opened


def _keep(question: tuple, opened: Packet | None) -> None:
    if len(_OPENED) >= _OPENED_LIMIT:
        _OPENED.popitem(last=False)   # (a dict's first key is a scan past deleted ones)
    _OPENED[question] = opened


class ReplayStore(AddressGrid):
    """The replay windows of every receiver of a process (the evaluator's brains, a
    composed container's agents; a ``FrameAuth`` alone has a store of its own): row p is
    receiver p, column c a source, and ``cells[p, c]`` = (highest counter accepted,
    bitmap of the ``WINDOW`` below it; 0: nothing heard yet)."""

    def __init__(self) -> None:
        super().__init__((0, 0), np.uint64)


_VERDICTS = (None, 'auth_replay', 'auth_too_old')
_ONE = np.uint64(1)


@kernel(np.zeros((1, 1, 2), dtype=np.uint64), np.zeros(1, dtype=np.int64), 0,
        np.uint64(5), np.uint64(64), np.uint64(COUNTER_MASK))
def _accept(cells: np.ndarray, rows: np.ndarray, col: int, counter: np.uint64,
            size: np.uint64, full: np.uint64) -> tuple[np.ndarray, int]:
    """The replay window (RFC 4303 3.4.3) of each receiver of ``rows`` for one frame of
    the source in column ``col``: 0 accepted (and recorded), 1 a replay, 2 too old; and
    how many were not accepted (most frames: none, known without a pass in Python).

    A counter above the highest moves the window; one inside it is accepted once; one
    below it is too old. All in unsigned 64-bit arithmetic, as the counters are.
    """
    verdict = np.zeros(rows.shape[0], dtype=np.int8)
    refused = 0
    for i in range(rows.shape[0]):
        cell = cells[rows[i], col]
        top, bits = cell[0], cell[1]
        if bits == 0 or counter > top:     # the first frame heard, or the next one
            shift = counter - top
            cell[1] = ((bits << shift) | _ONE) & full if bits != 0 and shift < size else _ONE
            cell[0] = counter
            continue
        offset = top - counter
        if offset >= size:
            verdict[i] = 2
            refused += 1
        elif (bits >> offset) & _ONE:
            verdict[i] = 1
            refused += 1
        else:
            cell[1] = bits | (_ONE << offset)
    return verdict, refused


class _Verifier:
    """The tag check of one keyring, shared by every ``FrameAuth`` of a process that holds
    it. A transmission is handed to its receivers one after another as the same object
    (the headless evaluator, a composed process's sensor batch): the last frame checked
    and its result are kept, so the next receivers pay an identity test."""

    def __init__(self, keyring: Keyring) -> None:
        self._keys = dict(keyring.keys)
        self._last: Packet | None = None
        self._result: tuple[Packet, int] | str = ''

    def __call__(self, packet: Packet) -> tuple[Packet, int] | str:
        """(the frame without its trailer, its counter) or the rejection kind."""
        if packet is self._last:
            return self._result
        result = self._check(packet)
        self._last, self._result = packet, result
        return result

    def _check(self, packet: Packet) -> tuple[Packet, int] | str:
        payload = packet.payload
        size = len(payload)
        if size < TRAILER_BYTES:
            return 'auth_short'
        key_id, counter = _TRAILER.unpack_from(payload, size - TRAILER_BYTES)
        key = self._keys.get(key_id)
        if key is None:
            return 'auth_unknown_key'
        try:
            opened = _verified(key, packet.source, packet.destination, packet.kind,
                               packet.sequence, packet.ttl, payload)
        except struct.error:   # header fields out of range: no radio sends those
            opened = None
        return 'auth_bad_tag' if opened is None else (opened, counter)


@functools.lru_cache(maxsize=64)
def _verifier(keyring: Keyring) -> _Verifier:
    return _Verifier(keyring)


class FrameAuth:
    """Seals this node's frames and opens those it hears; see the module docstring."""

    def __init__(self, keyring: Keyring, clock: Callable[[], float] = time.time,
                 window: int = WINDOW, store: ReplayStore | None = None) -> None:
        """``store`` holds the replay windows of the process's receivers (a frame is
        checked for all of them in one call, ``open_all``); None: one of its own."""
        if not 1 <= window <= WINDOW:
            raise FrameAuthError(f'replay window {window} must be 1..{WINDOW} counters')
        self.keyring = keyring
        self._seal_key = keyring.key(keyring.seal_id)
        self._verify = _verifier(keyring)
        self._counter = boot_counter(clock()) - 1
        self.store = store or ReplayStore()
        self.row = self.store.add_row()
        self._row = np.array([self.row], dtype=np.int64)   # its rows, alone
        self.window = window
        self._size = np.uint64(window)
        self._full = np.uint64((1 << window) - 1)
        self._group = self.store.group((self._verify, window))   # open_all's grouping
        self.stats: dict[str, int] = {}

    @property
    def counter(self) -> int:
        """The counter of the last frame sealed."""
        return self._counter

    def seal(self, packet: Packet) -> Packet:
        """The frame with the trailer appended to its payload."""
        self._counter = (self._counter + 1) & COUNTER_MASK
        body = packet.payload + _TRAILER.pack(self.keyring.seal_id, self._counter)
        tag = _tag(self._seal_key, _LINK.pack(
            packet.source, packet.destination, packet.kind, packet.sequence, packet.ttl)
            + body)
        sealed = Packet(packet.source, packet.destination, packet.kind, packet.sequence,
                        packet.ttl, body + tag)
        # What a receiver here holding the key will find: the tag need not be computed
        # again (the HMAC was 3 % of the headless evaluator).
        _keep((self._seal_key, packet.source, packet.destination, packet.kind,
               packet.sequence, packet.ttl, sealed.payload), packet)
        return sealed

    def open(self, packet: Packet) -> Packet | None:
        """The frame with the trailer removed, or None (counted) when it fails."""
        return open_all((self,), packet)[0]

    def _reject(self, kind: str) -> None:
        self.stats[kind] = self.stats.get(kind, 0) + 1
        return None


def auth_groups(auths: Sequence[FrameAuth]) -> list[tuple[list[int], np.ndarray]]:
    """``auths`` (distinct) grouped as ``open_all`` checks them: the positions that share a
    store, keyring and window, with their rows in the store. Receivers that hear frames
    together compute this once (``reception.Receivers``)."""
    first = auths[0]
    if len(auths) == 1:   # a node's own window, the mission's: one frame at a time
        return [([0], first._row)]
    if all(a._group is first._group for a in auths):   # one store, keyring and window
        return [(list(range(len(auths))), np.array([a.row for a in auths], dtype=np.int64))]
    keyed: dict[object, list[int]] = {}
    for i, a in enumerate(auths):
        keyed.setdefault(a._group, []).append(i)
    return [(group, np.array([auths[i].row for i in group], dtype=np.int64))
            for group in keyed.values()]


def open_all(auths: Sequence[FrameAuth], packet: Packet,
             groups: Sequence[tuple[list[int], np.ndarray]] | None = None
             ) -> list[Packet | None]:
    """``packet`` opened by each of ``auths`` (the receivers of one transmission in this
    process; distinct): the frame without its trailer, or None (counted by that
    receiver) when it fails. The tag is checked once per keyring, and each receiver's
    replay window is applied in one call per store (``_accept``). ``groups``:
    ``auth_groups(auths)``, when the caller keeps it."""
    out: list[Packet | None] = [None] * len(auths)
    for group, rows in groups or auth_groups(auths):
        auth = auths[group[0]]
        result = auth._verify(packet)
        if result.__class__ is str:
            for i in group:
                auths[i]._reject(result)
            continue
        opened, counter = result
        store = auth.store
        col = store.column_of(packet.source)     # may grow the cells: before reading them
        verdicts, refused = _accept(store.cells, rows, col, np.uint64(counter), auth._size,
                                    auth._full)
        if not refused and len(group) == len(auths):
            return [opened] * len(auths)     # one keyring, every window took it
        for i, verdict in zip(group, verdicts.tolist()):
            if verdict:
                auths[i]._reject(_VERDICTS[verdict])
            else:
                out[i] = opened
    return out


def main() -> None:
    """Print a new key file: ``python -m swarm_agent.frame_auth > swarm_keys.yaml``."""
    sys.stdout.write(new_key_file_text())


if __name__ == '__main__':
    main()
