"""Emitter and Receiver: Webots' radio, serial and infra-red links as in-process channels.

Pipeline (Webots' ``WbEmitter``/``WbReceiver``):

1. ``Emitter.send`` queues a packet (at least one byte) with the emitter's current channel and range; with a
   ``bufferSize`` the packet is refused when the queued bytes would exceed it.
2. At the next simulation step (before physics) the emitter releases its queue — all of it when ``baudRate`` is
   -1, else the whole packets that a byte budget allowed when its controller asked for that step: the budget grows
   by ``baudRate / byteSize / 1000`` per millisecond of each ``step`` the controller asks for (webots-devices.md
   §5.2 step 2: "per wb_robot_step", the controller library's count, not per basic step), and a packet larger than
   what is left waits for the next steps —
   to every receiver that is enabled at that moment, has the same ``type``, a matching channel (equal, or either
   is -1) and belongs to *another* robot.
3. After the physics step, radio and serial packets farther than the emitter's range (origin to origin) are
   dropped; infra-red ones also need a clear line of sight (a ray between the two origins hitting nothing but
   the two robots) and each end's ``aperture`` cone about its x axis (-1: all directions).
4. Signal strength ``1/d²`` times ``(1 + signalStrengthNoise·N(0,1))``, clamped at 0; emitter direction = the
   unit vector from the receiver to the emitter in the receiver's frame, with ``directionNoise·d·N(0,1)`` added to
   each component before normalising again.
5. At the receiver's sample the packets reach its queue, kept only if they fit its ``bufferSize`` (-1: any).

So a packet sent before ``step()`` *k* is readable when the receiver's ``step()`` *k* returns, if its sampling
period has elapsed.

``setChannel`` (Emitter, Receiver) and ``setRange`` (Emitter) also write the node's ``channel``/``range`` field:
Webots keeps these values in the device node's fields (emitter.md, receiver.md: setChannel "modifies the channel
field of the corresponding node"; WbEmitter handles the set-range message the same way), so a supervisor reading
the field sees what the controller set, and a restarted controller starts with it (its library reads the device's
fields when it connects).

``send`` with a ``str`` sends its UTF-8 bytes cut to ``len(str)`` (Webots' Python wrapper
does that); a list or tuple is packed as doubles, or as 32-bit ints when every item is an int or a bool. Not
modelled: the physics-plugin copy of channel 0. ``simulationReset`` clears every queue.

A supervisor's write of a field of either end (channel, range, maxRange, aperture, baudRate, bufferSize, noise...)
acts from the next step and the getters follow (Webots' update slots); a channel or range the controller set stays
until that same field is written.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualtwin.webots import _math3 as m3
from dualtwin.webots.api_args import as_float, as_int, error, warn
from dualtwin.webots.device_base import Device, SolidSensor, register_in_world_order
from dualtwin.webots.physics import Simulation
from dualtwin.webots.ranging import caster_for
from dualtwin.webots.rays import geom_list

__all__ = ["Emitter", "Receiver"]

CHANNEL_BROADCAST = -1


@dataclass
class _Packet:
    data: bytes
    channel: int
    range: float
    emitter: Emitter
    strength: float = 0.0
    direction: tuple[float, float, float] = (0.0, 0.0, 0.0)


def _channel_match(a: int, b: int) -> bool:
    return a in (b, CHANNEL_BROADCAST) or b == CHANNEL_BROADCAST


def _in_cone(R: m3.Mat3, towards: m3.Vec3, aperture: float) -> bool:
    if aperture < 0:
        return True
    x = m3.mat_vec(R, (1.0, 0.0, 0.0))
    n = m3.norm(towards)
    return n == 0.0 or math.acos(max(-1.0, min(1.0, m3.dot(x, towards) / n))) <= aperture / 2


class _Medium:
    """Per-simulation radio state: emitters with queued packets, enabled receivers, packets in flight."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.emitters: dict[int, Emitter] = {}
        self.receivers: dict[int, Receiver] = {}
        self.in_flight: list[tuple[_Packet, Receiver]] = []
        sim.pre_step_hooks.append(self.before_physics)
        sim.step_hooks.append(self.after_physics)
        sim.reset_hooks.append(self.reset)

    def reset(self) -> None:
        """simulationReset clears emitter and receiver queues (Webots' reset matrix)."""
        self.in_flight.clear()
        for emitter in self.emitters.values():
            emitter._queue.clear()
            emitter._ready.clear()
            emitter._budget = 0.0
        for receiver in self.receivers.values():
            receiver._arrived.clear()
            receiver._queue.clear()

    def before_physics(self, dt: float) -> None:
        # a supervisor's edit of the step before acts on this step's packets
        for emitter in self.emitters.values():
            emitter._follow()
        for receiver in self.receivers.values():
            receiver._follow()
        for emitter in list(self.emitters.values()):
            for packet in emitter._release(dt * 1000.0):
                for receiver in self.receivers.values():
                    if (
                        receiver._period > 0
                        and receiver._kind == emitter._kind
                        and _channel_match(packet.channel, receiver._channel)
                        and receiver._record.solid.robot is not emitter._record.solid.robot
                    ):
                        self.in_flight.append((packet, receiver))

    def after_physics(self) -> None:
        if not self.in_flight:
            return
        sim = self.sim
        for packet, receiver in self.in_flight:
            e_pose = sim.solid_world_pose(packet.emitter._record.solid)
            r_pose = sim.solid_world_pose(receiver._record.solid)
            delta = m3.sub(e_pose.t, r_pose.t)
            d = m3.norm(delta)
            if packet.range >= 0 and d > packet.range:
                continue
            if receiver._kind == "infra-red" and not self._infra_red_clear(
                packet, receiver, e_pose, r_pose, d
            ):
                continue
            strength = 1.0 / (d * d) if d > 0 else math.inf
            if receiver._strength_noise > 0 and math.isfinite(strength):
                strength = max(0.0, strength * (1.0 + receiver._strength_noise * sim.rng.gauss(0.0, 1.0)))
            local = m3.mat_t_vec(r_pose.R, delta)
            if receiver._direction_noise > 0:
                local = tuple(v + d * receiver._direction_noise * sim.rng.gauss(0.0, 1.0) for v in local)  # type: ignore[assignment]
            norm = m3.norm(local)
            direction = m3.scale(local, 1.0 / norm) if norm > 0 else (0.0, 0.0, 0.0)
            arrived = _Packet(packet.data, packet.channel, packet.range, packet.emitter, strength, direction)
            receiver._arrived.append(arrived)
        self.in_flight.clear()

    def _infra_red_clear(
        self, packet: _Packet, receiver: Receiver, e_pose: Any, r_pose: Any, d: float
    ) -> bool:
        emitter = packet.emitter
        if not _in_cone(e_pose.R, m3.sub(r_pose.t, e_pose.t), emitter._aperture):
            return False
        if not _in_cone(r_pose.R, m3.sub(e_pose.t, r_pose.t), receiver._aperture):
            return False
        if d == 0.0:
            return True
        # a ray from emitter to receiver: any Solid not of the emitting robot blocks the beam, whatever that
        # robot's selfCollision (§5.2 step 4: the emitter's own body, around its origin, never blocks it), nor
        # of the receiving robot (kept out as before: whether its selfCollision lets it block is not settled)
        ends = (emitter._record.solid.robot, receiver._record.solid.robot)
        geoms = geom_list(
            self.sim,
            ("infra-red", *map(id, ends)),
            lambda: [g for g in self.sim.geoms.values() if g.solid.robot not in ends],
        )
        origin = np.array([e_pose.t])
        direction = np.array([m3.scale(m3.sub(r_pose.t, e_pose.t), 1.0 / d)])
        hits = caster_for(self.sim).cast(origin, direction, d, geoms, normals=False)
        return not bool(np.isfinite(hits.distance[0]))


def _medium(sim: Simulation) -> _Medium:
    medium = sim.extensions.get("radio")
    if medium is None:
        medium = sim.extensions["radio"] = _Medium(sim)
    return medium


#: the fields each end reads (again after a supervisor's edit)
_EMITTER_FIELDS = ("type", "range", "maxRange", "aperture", "channel", "baudRate", "byteSize", "bufferSize",
                   "allowedChannels")
_RECEIVER_FIELDS = ("type", "aperture", "channel", "bufferSize", "signalStrengthNoise", "directionNoise",
                    "allowedChannels")


def _kind(fields: dict[str, Any]) -> str:
    kind = str(fields.get("type", "radio"))
    return kind if kind in ("radio", "serial", "infra-red") else "radio"


class Emitter(Device):
    """Webots ``Emitter`` (see the module docstring)."""

    CHANNEL_BROADCAST = CHANNEL_BROADCAST

    def _setup(self) -> None:
        self._follow()
        self._queue: list[_Packet] = []
        self._ready: list[_Packet] = []  # what the budget let go at the controller's last step request
        self._budget = 0.0
        register_in_world_order(_medium(self._robot._sim).emitters, self)
        # (always: a supervisor may give the emitter a baud rate at run time)
        self._robot.step_listeners.append(self._controller_step)

    def _follow(self) -> None:
        """Read the fields a supervisor edited (all of them at load), as WbEmitter's update slots: from the next
        step the packets go with the new channel and range, at the new rate, and the getters follow. A channel or
        range the controller set stays until that field is written."""
        changed = self._fields_changed(_EMITTER_FIELDS)
        if not changed:
            return
        f = self._fields()
        if "type" in changed:
            self._kind = _kind(f)
        if changed & {"range", "maxRange"}:
            self._max_range = float(f.get("maxRange", -1.0))
            r = float(f.get("range", -1.0))
            self._range = self._max_range if r < 0 else (min(r, self._max_range) if self._max_range >= 0 else r)
        if changed & {"type", "aperture"}:
            self._aperture = float(f.get("aperture", -1.0)) if self._kind == "infra-red" else -1.0
        if "channel" in changed:
            self._channel = int(f.get("channel", 0))
        self._baud = int(f.get("baudRate", -1))
        self._byte_size = max(8, int(f.get("byteSize", 8)))
        self._buffer_size = int(f.get("bufferSize", -1))
        self._allowed = [int(c) for c in f.get("allowedChannels", []) or []]

    def _controller_step(self, ms: float) -> None:
        """The controller asks for a step of ``ms``: the budget grows by what the baud rate sends in that time, and
        the whole packets it covers leave with the request (released at the step's first basic step)."""
        self._follow()
        if self._baud < 0:
            return
        self._budget += self._baud / self._byte_size / 1000.0 * ms
        while self._queue and len(self._queue[0].data) <= self._budget:
            packet = self._queue.pop(0)
            self._budget -= len(packet.data)
            self._ready.append(packet)
        if not self._queue:
            self._budget = 0.0

    def _release(self, ms: float) -> list[_Packet]:
        if self._baud < 0:
            # (a baudRate edited to -1 lets what was already released and what waits go together)
            out, self._ready, self._queue = self._ready + self._queue, [], []
            return out
        out, self._ready = self._ready, []
        return out

    def send(self, message: Any, length: Any = None) -> None:
        self._follow()
        if isinstance(message, str):
            data = message.encode("utf-8")[: len(message)]
        elif isinstance(message, (bytes, bytearray)):
            data = bytes(message)
        elif isinstance(message, (list, tuple)):
            ints = all(isinstance(v, (int, bool, np.integer)) for v in message)
            data = struct.pack(("i" if ints else "d") * len(message), *message)
        else:
            raise TypeError(f"Emitter.send(): unsupported message type {type(message).__name__}")
        if length is not None:
            data = data[: as_int(length, "Emitter.send")]
        if not data:
            warn("Emitter.send(): a packet needs at least one byte")
            return
        queued = sum(len(p.data) for p in self._queue)
        if self._buffer_size >= 0 and queued + len(data) > self._buffer_size:
            return  # the buffer is full: Webots drops the packet (send returns 0)
        self._queue.append(_Packet(data, self._channel, self._range, self))

    def getChannel(self) -> int:
        self._follow()
        return self._channel

    def setChannel(self, channel: Any) -> None:
        self._follow()
        c = as_int(channel, "Emitter.setChannel")
        if c < CHANNEL_BROADCAST or (self._allowed and c not in self._allowed):
            error(f"Emitter.setChannel(): channel {c} is not allowed")
            return
        self._channel = self._own_field("channel", c)

    def getRange(self) -> float:
        self._follow()
        return self._range

    def setRange(self, range: Any) -> None:  # noqa: A002 - Webots' parameter name
        self._follow()
        r = as_float(range, "Emitter.setRange")
        if r < 0:
            r = self._max_range
        elif self._max_range >= 0:
            r = min(r, self._max_range)
        self._range = self._own_field("range", r)

    def getBufferSize(self) -> int:
        self._follow()
        return self._buffer_size

    buffer_size = property(lambda self: self.getBufferSize())
    channel = property(lambda self: self.getChannel(), lambda self, channel: self.setChannel(channel))
    range = property(lambda self: self.getRange(), lambda self, range: self.setRange(range))  # noqa: A003


class Receiver(SolidSensor):
    """Webots ``Receiver`` (see the module docstring)."""

    CHANNEL_BROADCAST = CHANNEL_BROADCAST

    def _setup(self) -> None:
        self._follow()
        self._arrived: list[_Packet] = []
        self._queue: list[_Packet] = []
        register_in_world_order(_medium(self._robot._sim).receivers, self)

    def _follow(self) -> None:
        """Read the fields a supervisor edited (all of them at load), as WbReceiver's update slots (see
        :meth:`Emitter._follow`)."""
        changed = self._fields_changed(_RECEIVER_FIELDS)
        if not changed:
            return
        f = self._fields()
        self._kind = _kind(f)
        self._aperture = float(f.get("aperture", -1.0)) if self._kind == "infra-red" else -1.0
        if "channel" in changed:
            self._channel = int(f.get("channel", 0))
        self._buffer_size = int(f.get("bufferSize", -1))
        self._strength_noise = float(f.get("signalStrengthNoise", 0.0))
        self._direction_noise = float(f.get("directionNoise", 0.0))
        self._allowed = [int(c) for c in f.get("allowedChannels", []) or []]

    def _invalidate(self) -> None:
        pass  # the queue survives re-enabling, as in Webots

    def _read(self) -> None:
        self._follow()
        for packet in self._arrived:
            used = sum(len(p.data) for p in self._queue)
            if self._buffer_size < 0 or used + len(packet.data) <= self._buffer_size:
                self._queue.append(packet)
        self._arrived.clear()

    def disable(self) -> None:
        super().disable()
        self._arrived.clear()

    def getQueueLength(self) -> int:
        return len(self._queue)

    def nextPacket(self) -> None:
        if self._queue:
            self._queue.pop(0)

    def _head(self, method: str, report: Callable[[str], None] = warn) -> _Packet | None:
        if not self._queue:
            report(f"Receiver.{method}(): the receiver queue is empty")
            return None
        return self._queue[0]

    def getBytes(self) -> bytes:
        head = self._head("getBytes")
        return head.data if head is not None else b""

    def getString(self) -> str:
        head = self._head("getString")
        return head.data.decode("utf-8", errors="replace") if head is not None else ""

    getData = getString

    def getDataSize(self) -> int:
        head = self._head("getDataSize", error)  # webots-devices.md §5.3: "-1 + error if empty"
        return len(head.data) if head is not None else -1

    # getFloats/getInts/getBools: tuples, as Webots' wrapper returns what struct.unpack gives
    def getFloats(self) -> tuple[float, ...]:
        head = self._head("getFloats")
        return struct.unpack(f"{len(head.data) // 8}d", head.data[: len(head.data) // 8 * 8]) if head else ()

    def getInts(self) -> tuple[int, ...]:
        head = self._head("getInts")
        return struct.unpack(f"{len(head.data) // 4}i", head.data[: len(head.data) // 4 * 4]) if head else ()

    def getBools(self) -> tuple[bool, ...]:
        head = self._head("getBools")
        return tuple(bool(b) for b in head.data) if head is not None else ()

    def getSignalStrength(self) -> float:
        head = self._head("getSignalStrength")
        return head.strength if head is not None else math.nan

    def getEmitterDirection(self) -> list[float]:
        head = self._head("getEmitterDirection")
        return list(head.direction) if head is not None else [math.nan] * 3

    def getChannel(self) -> int:
        self._follow()
        return self._channel

    def setChannel(self, channel: Any) -> None:
        self._follow()
        c = as_int(channel, "Receiver.setChannel")
        if c < CHANNEL_BROADCAST or (self._allowed and c not in self._allowed):
            warn(f"Receiver.setChannel(): channel {c} is not allowed")
            return
        self._channel = self._own_field("channel", c)

    queue_length = property(lambda self: self.getQueueLength())
    data = property(lambda self: self.getData())
    data_size = property(lambda self: self.getDataSize())
    string = property(lambda self: self.getString())
    signal_strength = property(lambda self: self.getSignalStrength())
    emitter_direction = property(lambda self: self.getEmitterDirection())
    channel = property(lambda self: self.getChannel(), lambda self, channel: self.setChannel(channel))
