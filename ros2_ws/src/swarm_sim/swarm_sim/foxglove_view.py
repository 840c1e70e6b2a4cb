"""The live view on a Foxglove WebSocket: the scene as foxglove.SceneUpdate, the status.

``swarm_sim.live_view`` draws the swarm in plain data; this module turns it into
Foxglove's well-known schema (``to_scene_update``) and serves it (``LiveViewServer``,
channels ``/swarm/scene`` and ``/swarm/status``), for ``live_view_node`` and the tests.
"""

from __future__ import annotations

from collections.abc import Sequence

import foxglove
from foxglove import messages as fm
from foxglove.channels import SceneUpdateChannel

from swarm_sim import live_view as lv


def to_scene_update(entities: Sequence[lv.Entity], stamp_ns: int,
                    frame_id: str = lv.FRAME) -> fm.SceneUpdate:
    """A ``foxglove.messages.SceneUpdate``: delete every earlier entity, then these."""
    stamp = fm.Timestamp(sec=int(stamp_ns // 1_000_000_000), nsec=int(stamp_ns % 1_000_000_000))
    kinds = {'loop': fm.LinePrimitiveLineType.LineLoop,
             'strip': fm.LinePrimitiveLineType.LineStrip,
             'list': fm.LinePrimitiveLineType.LineList}

    def colour(c: lv.RGBA):
        return fm.Color(r=c[0], g=c[1], b=c[2], a=c[3])

    def pose(x: float, y: float, z: float):
        return fm.Pose(position=fm.Vector3(x=x, y=y, z=z),
                       orientation=fm.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))

    out = []
    for e in entities:
        out.append(fm.SceneEntity(
            timestamp=stamp, frame_id=frame_id, id=e.id,
            metadata=[fm.KeyValuePair(key=k, value=v) for k, v in e.metadata.items()],
            cylinders=[fm.CylinderPrimitive(
                pose=pose(d.x, d.y, d.z + 0.5 * d.height),
                size=fm.Vector3(x=2.0 * d.radius, y=2.0 * d.radius, z=d.height),
                bottom_scale=1.0, top_scale=1.0, color=colour(d.colour)) for d in e.discs],
            spheres=[fm.SpherePrimitive(
                pose=pose(b.x, b.y, b.z),
                size=fm.Vector3(x=b.diameter, y=b.diameter, z=b.diameter),
                color=colour(b.colour)) for b in e.balls],
            lines=[fm.LinePrimitive(
                type=kinds[ln.kind], pose=pose(0.0, 0.0, 0.0), thickness=ln.thickness,
                scale_invariant=False, color=colour(ln.colour),
                points=[fm.Point3(x=p[0], y=p[1], z=p[2]) for p in ln.points])
                for ln in e.lines],
            texts=[fm.TextPrimitive(
                pose=pose(t.x, t.y, t.z), billboard=True, font_size=t.size,
                scale_invariant=True, color=colour(t.colour), text=t.text)
                for t in e.labels]))
    deletion = fm.SceneEntityDeletion(timestamp=stamp, type=fm.SceneEntityDeletionType.All)
    return fm.SceneUpdate(deletions=[deletion], entities=out)


class LiveViewServer:
    """A Foxglove WebSocket server with the scene and status channels.

    Its own ``foxglove.Context``, so several servers (tests) do not share channels.
    ``OSError`` names the port when it cannot listen (taken, or not allowed).
    """

    def __init__(self, port: int = 8765, host: str = '127.0.0.1',
                 name: str = 'swarm live view') -> None:
        self.context = foxglove.Context()
        self.scene = SceneUpdateChannel(lv.SCENE_TOPIC, context=self.context)
        self.status = foxglove.Channel(lv.STATUS_TOPIC, schema=lv.STATUS_SCHEMA,
                                       context=self.context)
        try:
            self.server = foxglove.start_server(name=name, host=host, port=int(port),
                                                context=self.context)
        except Exception as exc:  # noqa: BLE001 - the SDK raises its own error types
            text = ' '.join(str(exc).split())
            raise OSError(f'cannot serve the live view on {host}:{port}: {text}; '
                          'pass -p port:=<a free port> '
                          '(or -p host:=<an address of this machine>)') from None

    @property
    def port(self) -> int:
        """The port it listens on (the one the OS chose when asked for 0)."""
        return int(self.server.port)

    def watched(self) -> bool:
        """True when a client subscribes to the scene or the status."""
        return self.scene.has_sinks() or self.status.has_sinks()

    def publish(self, view: lv.SwarmView, stamp_ns: int) -> None:
        """Send the scene and the status of ``view`` to the clients subscribed to them
        (nothing is built for a channel nobody subscribes to)."""
        if self.scene.has_sinks():
            self.scene.log(to_scene_update(lv.scene_entities(view), stamp_ns),
                           log_time=stamp_ns)
        if self.status.has_sinks():
            self.status.log(lv.status(view), log_time=stamp_ns)

    def stop(self) -> None:
        """Close the server (idempotent)."""
        self.server.stop()
