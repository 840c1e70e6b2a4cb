"""A run's ROS topics in an MCAP bag, written as they arrive (the writing part of
``recorder_node``).

The bag is what rosbag2's MCAP storage writes, so Foxglove, ``ros2 bag`` and the mcap
CLI open it: profile ``ros2``, one schema per message type with schema encoding
``ros2msg`` (the type's ``.msg`` text followed by every nested type's, each after a line
of ``=`` and ``MSG: pkg/msg/Type``, the concatenation rosbag2 and mcap-ros2-support
use) and messages as the CDR bytes the publisher sent (message encoding ``cdr``).
Times are integer nanoseconds; the recorder gives sim time.

Messages collect in a chunk (zstd-compressed) that is written out and flushed to the
file at least every ``flush_period_s`` (``flush_if_due``, called on every write and by
the recorder's wall-clock timer): a recorder killed without closing loses at most that
much, and ``read_messages`` reads a bag that was never closed up to its last flushed
chunk, with one warning line saying it was cut. The ``.msg`` files come from the
installed interface packages' share folders (ament_index). Pure: no ROS client library import.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
import logging
import pathlib
import re
import time
from typing import Any, BinaryIO

from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, IndexType, Writer

from swarm_common import qos

FLUSH_PERIOD_S = 1.0   # the most a killed recorder loses (issue 21: about a second)
SEPARATOR = '=' * 80   # between the definitions of a ros2msg schema, as rosbag2 writes
PRIMITIVES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'))
_BOUND = re.compile(r'<=\d+$')        # string<=10
_ARRAY = re.compile(r'\[[^\]]*\]$')   # T[], T[3], T[<=3]
_log = logging.getLogger(__name__)


# The swarm's own profiles (swarm_common.qos) of its topics, by full name or by the rest
# of a per-robot name (/agent_K/...), under any namespace (/swarm_a/swarm/goals); any
# other topic gets DEFAULT_QOS.
SWARM_QOS: dict[str, dict[str, int]] = {
    '/swarm/shape': qos.LATCHED, '/swarm/goals': qos.LATCHED,
    '/swarm/cmd_batch': qos.COMMAND_BATCH, '/swarm/sensor_batch': qos.RADIO,
    '/swarm/truth': qos.STATE, '/swarm/markers': qos.STATE, '/radio/tx': qos.RADIO,
    'radio/rx': qos.RADIO, 'imu': qos.IMU, 'cmd_force': qos.COMMAND, 'state': qos.STATE,
    'routes': qos.STATE, 'gps': qos.SENSOR, 'ranges': qos.SENSOR, 'proximity': qos.SENSOR,
    'cmd_vel': qos.SENSOR}
DEFAULT_QOS = {'history': qos.KEEP_LAST, 'depth': 100, 'reliability': qos.RELIABLE,
               'durability': qos.VOLATILE}


def swarm_profile(topic: str) -> dict[str, int]:
    """The swarm's profile of ``topic``: SWARM_QOS by full name, or by the rest of an
    ``/agent_K/...`` name, after any namespace; DEFAULT_QOS for a topic the swarm does not
    define."""
    parts = topic.strip('/').split('/')
    for i in range(len(parts)):   # without the first i tokens (a namespace)
        if (rest := '/' + '/'.join(parts[i:])) in SWARM_QOS:
            return SWARM_QOS[rest]
        if len(parts) - i >= 2 and parts[i].startswith('agent_') and \
                (robot := '/'.join(parts[i + 1:])) in SWARM_QOS:
            return SWARM_QOS[robot]
    return DEFAULT_QOS


def recording_qos(topic: str, offers: list[tuple[int, int]] = ()) -> dict[str, int]:
    """The subscription profile (``QoSProfile`` keywords) that records ``topic``.

    The swarm's profile of the topic (SWARM_QOS; DEFAULT_QOS for others), made compatible
    with the publishers' ``offers`` (reliability, durability) as rosbag2 does: reliable
    only if every publisher is, transient local (late joiners get the latched sample)
    only if every publisher is. Without offers, the swarm profile as it is.
    """
    profile = dict(swarm_profile(topic))
    if offers:
        profile['reliability'] = (qos.RELIABLE if all(r == qos.RELIABLE for r, _ in offers)
                                  else qos.BEST_EFFORT)
        profile['durability'] = (qos.TRANSIENT_LOCAL
                                 if all(d == qos.TRANSIENT_LOCAL for _, d in offers)
                                 else qos.VOLATILE)
    return profile


class BagError(ValueError):
    """A type without an installed definition, an unknown topic, a closed bag."""


def canonical_type(type_name: str) -> str:
    """``pkg/msg/Type`` of ``pkg/msg/Type`` or ``pkg/Type``."""
    parts = type_name.strip().split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3 or parts[1] != 'msg' or not all(parts):
        raise BagError(f'message type {type_name!r}: write it as package/msg/Type, '
                       'e.g. geometry_msgs/msg/Twist')
    return '/'.join(parts)


def installed_msg_file(type_name: str) -> pathlib.Path:
    """The ``.msg`` file of ``pkg/msg/Type`` in its installed package's share folder."""
    from ament_index_python.packages import (
        get_package_share_directory,
        PackageNotFoundError,
    )

    package, _, name = canonical_type(type_name).split('/')
    try:
        share = pathlib.Path(get_package_share_directory(package))
    except PackageNotFoundError:
        raise BagError(f'message type {type_name}: package {package} is not installed '
                       '(source its workspace, or run make bootstrap)') from None
    path = share / 'msg' / f'{name}.msg'
    if not path.is_file():
        raise BagError(f'message type {type_name}: no {path}; the package installs no '
                       '.msg file for it')
    return path


def nested_types(text: str, package: str) -> list[str]:
    """The message types the fields of a ``.msg`` text use, as ``pkg/msg/Type``, in
    order of appearance (``Header`` is std_msgs', a bare name is ``package``'s)."""
    found: list[str] = []
    for line in text.splitlines():
        words = line.split('#', 1)[0].split()
        if len(words) < 2:
            continue
        base = _BOUND.sub('', _ARRAY.sub('', words[0]))
        if base in PRIMITIVES:
            continue
        if base == 'Header':
            nested = 'std_msgs/msg/Header'
        elif '/' in base:
            nested = canonical_type(base)
        else:
            nested = f'{package}/msg/{base}'
        if nested not in found:
            found.append(nested)
    return found


def message_definition(type_name: str,
                       msg_file: Callable[[str], pathlib.Path] = installed_msg_file) -> str:
    """The ``ros2msg`` schema of a type: its ``.msg`` text, then each nested type's (depth
    first, each once) after a separator line and ``MSG: pkg/msg/Type``."""
    root = canonical_type(type_name)
    texts: dict[str, str] = {}
    pending = [root]
    while pending:
        current = pending.pop(0)
        if current in texts:
            continue
        texts[current] = msg_file(current).read_text(encoding='utf-8').rstrip('\n')
        pending[:0] = [t for t in nested_types(texts[current], current.split('/')[0])
                       if t not in texts]
    parts = [texts[root]]
    for name, text in texts.items():
        if name != root:
            parts.append(f'{SEPARATOR}\nMSG: {name}\n{text}')
    return '\n'.join(parts) + '\n'


class BagWriter:
    """An MCAP bag of ROS 2 messages, flushed chunk by chunk.

    ``add_topic`` registers a topic with its type (and schema, once per type); ``write``
    adds a message's CDR bytes; ``close`` writes the summary and closes the file. The
    clock measures the flush period (wall time, ``time.monotonic`` by default).
    """

    def __init__(self, path: str | pathlib.Path, flush_period_s: float = FLUSH_PERIOD_S,
                 clock: Callable[[], float] = time.monotonic,
                 definition: Callable[[str], str] = message_definition) -> None:
        if not flush_period_s > 0.0:
            raise BagError(f'flush period {flush_period_s:g} s: give a period above 0 s '
                           f'(default {FLUSH_PERIOD_S:g})')
        self.path = pathlib.Path(path)
        if not self.path.parent.is_dir():
            raise BagError(f'bag {self.path}: folder {self.path.parent} does not exist; '
                           'create it or write the bag elsewhere')
        self.flush_period_s = flush_period_s
        self._clock = clock
        self._definition = definition
        self._file: BinaryIO = open(self.path, 'wb')  # noqa: SIM115 - closed by close()
        # The chunk size is only a ceiling: flush_if_due ends chunks by time. No message
        # indexes: the writer keeps every chunk's index for the summary, and one index
        # offset per topic made that 16 kB a chunk (58 MiB an hour with 223 topics);
        # readers find the messages in the chunks themselves (MCAP makes them optional).
        self._writer = Writer(self._file, chunk_size=4 * 1024 * 1024,
                              compression=CompressionType.ZSTD,
                              index_types=IndexType.ALL & ~IndexType.MESSAGE)
        self._writer.start(profile='ros2', library='swarm_bringup.bag (mcap)')
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self.types: dict[str, str] = {}
        self.counts: dict[str, int] = {}
        self.unflushed = 0
        self._last_flush = clock()
        self.closed = False
        self.flush()

    def add_topic(self, topic: str, type_name: str) -> None:
        """Register ``topic`` carrying ``type_name`` (``pkg/msg/Type``); BagError if the
        type has no installed definition or the topic already carries another type."""
        type_name = canonical_type(type_name)
        if topic in self._channels:
            if self.types[topic] != type_name:
                raise BagError(f'topic {topic} is recorded as {self.types[topic]}, '
                               f'not {type_name}')
            return
        self._check_open()
        if type_name not in self._schemas:
            self._schemas[type_name] = self._writer.register_schema(
                type_name, 'ros2msg', self._definition(type_name).encode())
        self._channels[topic] = self._writer.register_channel(
            topic, 'cdr', self._schemas[type_name])
        self.types[topic] = type_name
        self.counts[topic] = 0

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: int | None = None) -> None:
        """Add one message (its serialized CDR bytes) of a registered topic."""
        self._check_open()
        channel = self._channels.get(topic)
        if channel is None:
            raise BagError(f'topic {topic} is not registered; call add_topic first')
        self._writer.add_message(
            channel, log_time=int(log_time_ns), data=bytes(data),
            publish_time=int(log_time_ns if publish_time_ns is None else publish_time_ns),
            sequence=self.counts[topic])
        self.counts[topic] += 1
        self.unflushed += 1
        self.flush_if_due()

    def flush_if_due(self) -> bool:
        """Flush when ``flush_period_s`` has passed since the last flush; True if done."""
        if self.closed or self._clock() - self._last_flush < self.flush_period_s:
            return False
        self.flush()
        return True

    def flush(self) -> None:
        """End the open chunk and push everything written to the file (the OS keeps it
        if the process is killed)."""
        self._check_open()
        # The writer ends chunks by size only; ending one by time has no public call.
        self._writer._Writer__finalize_chunk()  # noqa: SLF001
        self._file.flush()
        self.unflushed = 0
        self._last_flush = self._clock()

    def close(self) -> None:
        """Write the summary (indexes, statistics) and close the file. Idempotent."""
        if self.closed:
            return
        self._writer.finish()
        self._file.close()
        self.closed = True

    def _check_open(self) -> None:
        if self.closed:
            raise BagError(f'bag {self.path} is closed')

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_raw(path: str | pathlib.Path) -> Iterator[tuple[Channel, Schema | None, Message]]:
    """Every message of a bag in file order with its channel and schema; a bag never
    closed (its writer killed: no footer) is read up to its last complete record, and
    one warning line says so."""
    with open(path, 'rb') as stream:
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        records = StreamReader(stream, skip_magic=False, emit_chunks=False).records
        count, last_ns = 0, 0
        while True:
            try:
                record = next(records)
            except (StopIteration, McapError, EOFError, ValueError, OSError):
                # The end, or a truncated tail: everything before it was read.
                _log.warning('bag %s was cut (its recorder was killed): %d messages up to '
                             't=%.1f s read', path, count, last_ns / 1e9)
                return
            if isinstance(record, Footer):
                return
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels[record.channel_id]
                count, last_ns = count + 1, max(last_ns, record.log_time)
                yield channel, schemas.get(channel.schema_id), record


def read_messages(path: str | pathlib.Path) -> Iterator[tuple[str, str, int, Any]]:
    """Every message of a bag as ``(topic, type, log_time_ns, decoded message)``,
    decoded by mcap-ros2-support from the bag's own schemas (no ROS install needed)."""
    from mcap_ros2.decoder import DecoderFactory

    factory = DecoderFactory()
    decoders: dict[int, Callable[[bytes], Any]] = {}
    for channel, schema, message in read_raw(path):
        if channel.id not in decoders:
            decoder = factory.decoder_for(channel.message_encoding, schema)
            if decoder is None:
                raise BagError(f'bag {path}: topic {channel.topic} has no ros2msg schema')
            decoders[channel.id] = decoder
        yield (channel.topic, schema.name if schema else '', message.log_time,
               decoders[channel.id](message.data))
