"""frond receiver: drive an armature live from frond-osc, and record what arrives into an action.

Install: Edit > Preferences > Add-ons > Install from Disk, pick this file (or copy it into
Blender's scripts/addons folder), enable "frond receiver". The panel is in the 3D view sidebar
(N), tab "frond".

Start `frond-osc --target 127.0.0.1:9000` (the `frond` namespace, the default), pick the armature
(for instance one imported from a GLB that frond-gltf baked: File > Import > glTF 2.0) and press
Listen. The bones are found by the joint names frond-osc announces (`/frond/rig`: the daemon's
rig and its four joint names, root first, repeated every second), so an armature imported from
frond-gltf's GLB of any rig (`root/lower/middle/tip` for grass, `root/stem_low/stem_high/head` for
the flower, ...) is driven as it is; before any announcement, or for bones missing from the
armature, the names `joint0` .. `joint3` are tried. Secondary elements: a layer (`leaf`,
`leaf#2`) drives every instance of its kind in the picked armature (`leaf0_joint0`, ...); a field
plant (`plant<i>` of `frond field start`) or a graph walker (`walker<i>` of `frond walk`) drives
the armature of plant i wherever it is in the scene, as Blender imports a field or grove GLB from
frond-gltf (`<rig>_<i>`, zero-padded: `grass_03`), so live fields need no armature picked. A
running field that frond-osc sends whole (`/frond/field/<f>/...`) is drawn whole: every plant
evaluated here (numpy, `frond_motion::field_eval` ported) and each plant's armature driven, the
announced plants' own poses then skipped (see "Whole fields" in exporters/osc/README.md); Build
field plants makes the armatures of a field's plants from one plant, without importing them. Every
received frame sets the bones' rotations from `/frond/joint/<i>/quat`; Record keys each received
frame into a new action at the frame given by the pose's device time `t` (`start frame + (t - t0)
* scene fps`, fractional frames kept so no frame is lost; frames flagged held, which repeat the
previous pose, are applied but not keyed). Frames flagged device-lost (`/frond/status` bit 2)
are not applied or keyed: the armature holds its last pose.

Axes: frond's joint frame has the stem along +Y, pitch about +X, yaw about +Z (right-handed,
glTF). A Blender bone pointing along its parent's direction with roll 0 has exactly these local
axes (bone Y along the bone; in a Z-up scene bone X = world X, bone Z = world -Y, which is where
glTF's +Z lands), and Blender's glTF importer gives the bones of frond-gltf's GLBs the glTF
joints' own frames, so frond's quaternion (x, y, z, w) is the pose bone's `rotation_quaternion`
(w, x, y, z) unchanged.

No dependency beyond Blender: OSC is decoded here (OSC 1.0 bundles and messages).
"""

import socket
import struct
import time

bl_info = {
    "name": "frond receiver",
    "author": "frond",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "3D View > Sidebar > frond",
    "description": "Drive an armature live from frond-osc (OSC) and record the frames into an action",
    "category": "Animation",
}

try:
    import bpy
except ImportError:  # the OSC parsing below is usable without Blender
    bpy = None

BONE_NAMES = ("joint0", "joint1", "joint2", "joint3")  # before /frond/rig names the joints
HELD = 1
DEVICE_LOST = 2


# ---------------------------------------------------------------- OSC decoding (no Blender needed)


class OscError(ValueError):
    pass


MAX_BUNDLE_DEPTH = 8  # bundles within bundles: deeper is refused (a datagram of nested headers)


def _is_int(v):
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v):
    """A finite int or float (OSC's i, h, f, d), not a bool."""
    import math

    return (isinstance(v, float) and math.isfinite(v)) or _is_int(v)


def _element_id(address):
    """`<e>` of `/frond/element/<e>/...`: a protocol element id, 1 to 65535."""
    digits = address.split("/")[3]
    if not digits.isdigit() or not 0 < int(digits) < 65536:
        raise OscError(f"{address[:80]}: no element id")
    return int(digits)


def _string(data, i):
    end = data.index(b"\0", i)
    s = data[i:end].decode("utf-8")
    return s, (end + 4) & ~3


def _message(data):
    address, i = _string(data, 0)
    if i >= len(data):
        return address, []
    tags, i = _string(data, i)
    if not tags.startswith(","):
        raise OscError(f"{address}: type tags {tags!r} do not start with ','")
    args = []
    for tag in tags[1:]:
        if tag == "i":
            args.append(struct.unpack_from(">i", data, i)[0])
            i += 4
        elif tag == "f":
            args.append(struct.unpack_from(">f", data, i)[0])
            i += 4
        elif tag == "d":
            args.append(struct.unpack_from(">d", data, i)[0])
            i += 8
        elif tag == "h":
            args.append(struct.unpack_from(">q", data, i)[0])
            i += 8
        elif tag == "s":
            s, i = _string(data, i)
            args.append(s)
        elif tag == "b":
            (size,) = struct.unpack_from(">i", data, i)
            if size < 0 or i + 4 + size > len(data):
                raise OscError(f"{address}: blob of {size} bytes does not fit")
            args.append(bytes(data[i + 4 : i + 4 + size]))
            i += 4 + ((size + 3) & ~3)
        elif tag in "TF":
            args.append(tag == "T")
        elif tag == "N":
            args.append(None)
        else:
            raise OscError(f"{address}: unsupported type tag {tag!r}")
    return address, args


def parse_packet(data, depth=0):
    """Returns [(timetag or None, address, args)] for a datagram (bundle or message)."""
    if depth > MAX_BUNDLE_DEPTH:
        raise OscError(f"bundles nested deeper than {MAX_BUNDLE_DEPTH}")
    if data.startswith(b"#bundle\0"):
        if len(data) < 16:
            raise OscError("truncated bundle header")
        tag = struct.unpack_from(">Q", data, 8)[0]
        out, i = [], 16
        while i < len(data):
            (size,) = struct.unpack_from(">I", data, i)
            i += 4
            if size % 4 or i + size > len(data):
                raise OscError(f"bundle element of {size} bytes does not fit")
            for _, address, args in parse_packet(data[i : i + size], depth + 1):
                out.append((tag, address, args))
            i += size
        return out
    address, args = _message(data)
    return [(None, address, args)]


def frame_from_messages(messages):
    """A frame dict from one bundle's messages of the frond namespace, or None if incomplete."""
    frame = {"quats": [None] * 4}
    for tag, address, args in messages:
        frame["timetag"] = tag
        if address == "/frond/pose" and len(args) == 14:
            if not (_is_int(args[0]) and all(_is_number(a) for a in args[1:])):
                raise OscError("/frond/pose: arguments of the wrong type or not finite")
            frame["seq"], frame["t"], frame["angles"] = args[0], args[1], list(args[2:14])
        elif address.startswith("/frond/joint/") and address.endswith("/quat") and len(args) == 4:
            i = address.split("/")[3]
            if i in ("0", "1", "2", "3"):
                if not all(_is_number(a) for a in args):
                    raise OscError(f"{address}: a rotation of the wrong type or not finite")
                frame["quats"][int(i)] = tuple(args)
        elif address == "/frond/status" and args:
            if not _is_int(args[0]):
                raise OscError("/frond/status: flags are not an integer")
            frame["flags"] = args[0]
    if "seq" not in frame or any(q is None for q in frame["quats"]):
        return None
    frame.setdefault("flags", 0)
    return frame


def joint_quat(pitch, yaw, roll):
    """frond's convention (stem +Y, R = R_yaw(Z) R_pitch(X) R_roll(Y)) as (x, y, z, w)."""
    import math

    def axis(i, deg):
        h = math.radians(deg) / 2
        v = [0.0, 0.0, 0.0]
        v[i] = math.sin(h)
        return (v[0], v[1], v[2], math.cos(h))

    def mul(a, b):
        ax, ay, az, aw = a
        bx, by, bz, bw = b
        return (
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        )

    return mul(mul(axis(2, yaw), axis(0, pitch)), axis(1, roll))


def element_frame_from_messages(messages):
    """An element frame dict ({"element", "seq", "t", "quats"}) from a bundle holding
    `/frond/element/<e>/pose`, or None."""
    for tag, address, args in messages:
        if address.startswith("/frond/element/") and address.endswith("/pose") and len(args) == 14:
            if not (_is_int(args[0]) and all(_is_number(a) for a in args[1:])):
                raise OscError(f"{address[:80]}: arguments of the wrong type or not finite")
            e = _element_id(address)
            a = list(args[2:14])
            quats = [joint_quat(*a[3 * j : 3 * j + 3]) for j in range(4)]
            return {"element": e, "timetag": tag, "seq": args[0], "t": args[1], "quats": quats, "flags": 0}
    return None


# ---------------------------------------------------------------- whole fields (numpy, no Blender needed)
#
# frond-osc sends each running field whole (protocol 3; seed 000, Eq. 6-7 and section 6.3): its
# definition (`/frond/field/<f>/def`, `/joints`), its plants' layout in chunks (`/layout`) and
# every field frame (`/frame`: stream time, controls, stream frames). The add-on evaluates every
# plant itself with the equations of daemon/motion/src/field_eval.rs, ported from the console's
# page/field.js and vectorised over plants: angles are float32 where Rust has f32, everything
# else float64, in the same order of operations.
#
# Plant B of row r at stream time tau shows, for joint i, the stream at
#   tau + start_r / fps - K (gamma_B + delta_i),   gamma_B = ((B - A_r) . d) / V_M
# interpolated linearly between frames and clamped to the history held, then scaled and its
# bend (pitch, yaw) turned by direction - authored_direction.

MAX_HISTORY = 1 << 18  # frond_protocol::field::MAX_FIELD_HISTORY_FRAMES
MAX_FIELD_PLANTS = 100_000  # frond-osc's MAX_OSC_FIELD_PLANTS: larger fields are not sent whole
MAX_LAYOUT_CHUNKS = 2000  # frond-osc's MAX_LAYOUT_CHUNKS
MAX_CHUNK_BYTES = 1100  # a chunk fits a 1200-byte datagram
MAX_FIELDS = 8  # frond_protocol::field::MAX_WIRE_FIELDS
MAX_STREAM_FPS = 1000.0
MAX_ENTRIES = 12  # frond_protocol::field::FIELD_FRAME_ENTRIES
ENTRY_BYTES = 8 + 12 * 4
LAYOUT_BYTES_PER_PLANT = 20
MAX_PENDING_FRAMES = 256  # field frames kept before a layout is complete


class StreamHistory:
    """The last `capacity` frames of a field's driving stream (12 angles each), by stream index
    (field_eval.rs `StreamHistory`)."""

    def __init__(self, capacity):
        import numpy as np

        self.cap = min(max(int(capacity), 2), MAX_HISTORY)
        self.frames = np.zeros((self.cap, 12), dtype=np.float32)
        self.held = np.zeros(self.cap, dtype=np.int64)  # index + 1 of the frame in each slot, 0 empty
        self.produced = 0

    def oldest(self):
        return max(0, self.produced - self.cap)

    def insert(self, index, joints):
        """Records frame `index` (12 float32 angles); one older than the window is ignored."""
        if index < self.oldest() or index >= (1 << 62):
            return
        self.produced = max(self.produced, index + 1)
        slot = index % self.cap
        self.frames[slot] = joints
        self.held[slot] = index + 1

    def at_indices(self, f, columns):
        """The stream at fractional indices `f` (float64 array), only `columns` of its 12
        angles: (values float32 (n, len(columns)), ok (n,) bool: every frame needed held)."""
        import numpy as np

        n = f.shape[0]
        if self.produced == 0:
            return np.zeros((n, len(columns)), dtype=np.float32), np.zeros(n, dtype=bool)
        lo, hi = float(self.oldest()), float(self.produced - 1)
        x = np.where(np.isnan(f), lo, np.clip(f, lo, hi))
        k = np.floor(x)
        u = x - k
        ka = k.astype(np.int64)
        sa = ka % self.cap
        ok = self.held[sa] == ka + 1
        a = self.frames[sa][:, columns]
        between = u != 0.0
        kb = ka + 1
        sb = kb % self.cap
        ok &= ~between | (self.held[sb] == kb + 1)
        b = self.frames[sb][:, columns]
        a64 = a.astype(np.float64)
        lerp = (a64 + u[:, None] * (b.astype(np.float64) - a64)).astype(np.float32)
        return np.where(between[:, None], lerp, a), ok


def _heading(deg):
    import math

    r = deg * (math.pi / 180.0)
    return math.cos(r), -math.sin(r)


class FieldEval:
    """A field's plants evaluated together (field_eval.rs `FieldState`): layout arrays,
    the stream history, the controls in force and every plant's Eq. 7 delay under them."""

    def __init__(self, positions, rows, start_frames, row_count, authored_deg, fps, history):
        import numpy as np

        self.positions = positions.astype(np.float64)  # (n, 2) from float32 metres
        self.rows = rows.astype(np.int64)
        self.start = start_frames.astype(np.float64)
        self.n = rows.shape[0]
        self.row_count = row_count
        self.authored = authored_deg
        self.fps = fps
        self.history = history
        self.controls = None
        self.delays = np.zeros(self.n)

    def set_controls(self, c):
        """Eq. 7 for every plant under controls `c` (a tuple: direction_deg, speed_m_s,
        time_step, scale (float32), delays_s (3))."""
        import numpy as np

        self.controls = c
        d0, d1 = _heading(c[0])
        proj = self.positions[:, 0] * d0 + self.positions[:, 1] * d1
        upwind = np.full(self.row_count, np.inf)
        np.minimum.at(upwind, self.rows, proj)
        v = max(c[1], 1e-6)
        self.delays = (proj - upwind[self.rows]) / v

    def evaluate(self, tau):
        """Every plant at stream time `tau`: (angles float32 (n, 12), [pitch, yaw, roll] per
        joint, root first, degrees; ok (n,) bool: False where the history lacks a frame)."""
        import math

        import numpy as np

        c = self.controls
        direction, _, step, scale, delays_s = c
        base = tau + self.start / self.fps - step * self.delays
        out = np.zeros((self.n, 12), dtype=np.float32)
        ok = np.ones(self.n, dtype=bool)
        for j in range(4):
            delta = 0.0 if j == 0 else delays_s[j - 1]
            at = base - step * delta
            values, held = self.history.at_indices(at * self.fps, [3 * j, 3 * j + 1, 3 * j + 2])
            out[:, 3 * j : 3 * j + 3] = values
            ok &= held
        # shape_pose: every angle scaled (float32), then the bend turned.
        out *= np.float32(scale)
        rot = direction - self.authored
        if rot != 0.0:
            r = rot * (math.pi / 180.0)
            s, co = math.sin(r), math.cos(r)
            p = out[:, 0::3].astype(np.float64)
            y = out[:, 1::3].astype(np.float64)
            out[:, 0::3] = (p * co + y * s).astype(np.float32)
            out[:, 1::3] = (y * co - p * s).astype(np.float32)
        return out, ok


def joint_quats(angles):
    """frond's joint quaternions (`joint_quat`, R = R_yaw R_pitch R_roll) of float32 angles
    (n, 12): (n, 4, 4) as (w, x, y, z) per joint, Blender's order."""
    import numpy as np

    a = np.radians(angles.astype(np.float64)).reshape(-1, 4, 3) * 0.5
    sp, cp = np.sin(a[..., 0]), np.cos(a[..., 0])
    sy, cy = np.sin(a[..., 1]), np.cos(a[..., 1])
    sr, cr = np.sin(a[..., 2]), np.cos(a[..., 2])
    # q_yaw * q_pitch = (cy sp, sy sp, sy cp, cy cp), then * q_roll (0, sr, 0, cr).
    x1, y1, z1, w1 = cy * sp, sy * sp, sy * cp, cy * cp
    x = x1 * cr - z1 * sr
    y = w1 * sr + y1 * cr
    z = z1 * cr + x1 * sr
    w = w1 * cr - y1 * sr
    return np.stack([w, x, y, z], axis=-1)


class FieldDef:
    """What `/frond/field/<f>/def` says, checked against the limits."""

    FIELDS = ("source", "rig", "plants", "rows", "cols", "fps", "history", "authored", "publish_hz",
              "key", "layout_bytes", "chunk_bytes", "chunks", "announced")

    def __init__(self, args):
        import math

        types = (str, str, int, int, int, float, int, float, int, int, int, int, int, bytes)
        if len(args) != len(types) or not all(isinstance(a, t) for a, t in zip(args, types)):
            raise OscError("field definition: wrong arguments")
        for name, value in zip(self.FIELDS, args):
            setattr(self, name, value)
        self.key &= 0xFFFFFFFF
        if not 0 < self.plants <= MAX_FIELD_PLANTS:
            raise OscError(f"field definition: {self.plants} plants (1..={MAX_FIELD_PLANTS})")
        if self.rows < 1 or self.cols < 1 or self.rows * self.cols > 1_000_000:
            raise OscError("field definition: rows or columns out of range")
        if not (math.isfinite(self.fps) and 0 < self.fps <= MAX_STREAM_FPS and math.isfinite(self.authored)):
            raise OscError("field definition: stream fps or direction out of range")
        if not 2 <= self.history <= MAX_HISTORY:
            raise OscError(f"field definition: history of {self.history} frames")
        if self.layout_bytes != self.plants * LAYOUT_BYTES_PER_PLANT or not 0 < self.chunk_bytes <= MAX_CHUNK_BYTES:
            raise OscError("field definition: layout size does not match the plants")
        if self.chunks != -(-self.layout_bytes // self.chunk_bytes) or self.chunks > MAX_LAYOUT_CHUNKS:
            raise OscError(f"field definition: {self.chunks} layout chunks")
        if len(self.announced) % 2 or len(self.announced) > 128:
            raise OscError("field definition: announced plants")
        self.announced = tuple(struct.unpack(f"<{len(self.announced) // 2}H", self.announced))

    def same(self, other):
        return other is not None and all(getattr(self, k) == getattr(other, k) for k in self.FIELDS)


class LiveField:
    """One field as the add-on keeps it: its definition, the layout chunks put together, the
    stream history (filled from the definition on, before the layout is complete) and, once
    the layout is whole, its `FieldEval`."""

    def __init__(self, fid, definition):
        self.id = fid
        self.definition = definition
        self.joints = None  # the rig's four joint names (`/frond/field/<f>/joints`)
        self.chunks = {}
        self.history = StreamHistory(definition.history)
        self.eval = None
        self.controls = None
        self.frame = None  # the newest frame applied: {"seq", "t", "flags", "tau"}
        self.frames = 0  # field frames applied
        self.drawn_seq = None  # the frame the armatures show
        self.targets = None  # Blender: [(plant, armature, [pose bones])], see field_targets
        self.scene_objects = -1
        self.last_drive = None
        self.scales = None  # with the layout whole: every plant's scale

    def add_chunk(self, key, index, count, data):
        """Takes one layout chunk; a chunk of another layout (key, count) or size is ignored.
        Whether the layout became whole (and the evaluator was made)."""
        d = self.definition
        if self.eval is not None or key & 0xFFFFFFFF != d.key or count != d.chunks or not 0 <= index < count:
            return False
        want = min(d.chunk_bytes, d.layout_bytes - index * d.chunk_bytes)
        if len(data) != want:
            return False
        self.chunks[index] = data
        if len(self.chunks) < d.chunks:
            return False
        return self._make_eval()

    def _make_eval(self):
        import zlib

        import numpy as np

        d = self.definition
        layout = b"".join(self.chunks[i] for i in range(d.chunks))
        self.chunks = {}
        if len(layout) != d.layout_bytes or zlib.crc32(layout) != d.key:
            return False  # a foreign or damaged layout: the next pass brings it again
        n = d.plants
        positions = np.frombuffer(layout, dtype="<f4", count=2 * n).reshape(n, 2)
        rows = np.frombuffer(layout, dtype="<u4", count=n, offset=8 * n)
        starts = np.frombuffer(layout, dtype="<u4", count=n, offset=12 * n)
        scales = np.frombuffer(layout, dtype="<f4", count=n, offset=16 * n)
        if not np.isfinite(positions).all() or (rows >= d.rows).any() or not np.isfinite(scales).all():
            return False
        self.scales = scales.astype(np.float64)  # each plant's size factor (`build_field`)
        self.eval = FieldEval(positions, rows, starts, d.rows, d.authored, d.fps, self.history)
        if self.controls is not None:
            self.eval.set_controls(self.controls)
        return True

    def apply_frame(self, frame):
        """One field frame (`decode_field_frame`) into the history, controls and stream time
        (field_wire.rs `apply_frame`)."""
        for index, joints in frame["entries"]:
            if index < frame["produced"]:
                self.history.insert(index, joints)
        c = frame["controls"]
        if c != self.controls:
            self.controls = c
            if self.eval is not None:
                self.eval.set_controls(c)
        self.frame = {"seq": frame["seq"], "t": frame["t"], "flags": frame["flags"], "tau": frame["tau"]}
        self.frames += 1

    def ready(self):
        return self.eval is not None and self.controls is not None


def decode_field_frame(args):
    """`/frond/field/<f>/frame ,hidddddfdddhb` as a dict, or None when a value is out of range."""
    import math

    import numpy as np

    if len(args) != 13 or not isinstance(args[12], bytes):
        return None
    seq, flags, t, tau, direction, speed, step, scale, d1, d2, d3, produced, blob = args
    values = (t, tau, direction, speed, step, scale, d1, d2, d3)
    if not all(isinstance(v, float) and math.isfinite(v) for v in values) or not (_is_int(seq) and _is_int(flags)):
        return None
    if not isinstance(produced, int) or produced < 0 or len(blob) % ENTRY_BYTES or len(blob) > MAX_ENTRIES * ENTRY_BYTES:
        return None
    entries = []
    for o in range(0, len(blob), ENTRY_BYTES):
        (index,) = struct.unpack_from("<Q", blob, o)
        joints = np.frombuffer(blob, dtype="<f4", count=12, offset=o + 8)
        entries.append((index, joints))
    # scale travels as f32: kept float32, as Rust multiplies by it in f32.
    controls = (direction, speed, step, np.float32(scale), (d1, d2, d3))
    return {"seq": seq, "flags": flags, "t": t, "tau": tau, "controls": controls, "produced": produced,
            "entries": entries}


class FieldReceiver:
    """The running fields frond-osc sends whole, from the messages of each datagram."""

    def __init__(self):
        self.fields = {}
        self.refused = 0  # definitions, chunks or frames out of their limits

    def read(self, messages):
        for _, address, args in messages:
            if address == "/frond/fields":
                ids = {a for a in args if isinstance(a, int)}
                for fid in [f for f in self.fields if f not in ids]:
                    del self.fields[fid]
                continue
            parts = address.split("/")
            if len(parts) != 5 or parts[1] != "frond" or parts[2] != "field" or not parts[3].isdigit():
                continue
            fid, what = int(parts[3]), parts[4]
            if not 0 < fid < 65536:
                continue
            if what == "def":
                try:
                    definition = FieldDef(args)
                except OscError:
                    self.refused += 1
                    continue
                old = self.fields.get(fid)
                if old is None or not definition.same(old.definition):
                    if old is None and len(self.fields) >= MAX_FIELDS:
                        self.refused += 1
                        continue
                    self.fields[fid] = LiveField(fid, definition)
                continue
            field = self.fields.get(fid)
            if field is None:
                continue
            if what == "joints" and len(args) == 4 and all(isinstance(a, str) for a in args):
                field.joints = tuple(args)
            elif what == "layout" and len(args) == 4 and isinstance(args[3], bytes):
                if not all(isinstance(a, int) for a in args[:3]):
                    continue
                field.add_chunk(args[0], args[1], args[2], args[3])
            elif what == "frame":
                frame = decode_field_frame(args)
                if frame is None:
                    self.refused += 1
                else:
                    field.apply_frame(frame)

    def evaluated(self):
        """The fields whose every plant can be evaluated (layout whole, controls known)."""
        return [f for f in self.fields.values() if f.ready()]


class Receiver:
    """A non-blocking UDP socket; `poll()` drains it and returns the complete frames, in order."""

    def __init__(self, host="127.0.0.1", port=9000):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind((host, port))
        self.sock.setblocking(False)
        self.malformed = 0
        self.rig = None
        self.joint_names = None
        self.elements = {}
        self.fields = FieldReceiver()

    @property
    def port(self):
        return self.sock.getsockname()[1]

    def read_names(self, messages):
        """Takes the announced names: `/frond/rig` (rig, 4 joints) and `/frond/element/<e>/info`
        (name, kind, rig, 4 joints)."""
        for _, address, args in messages:
            if address == "/frond/rig" and len(args) == 5 and all(isinstance(a, str) for a in args):
                self.rig, self.joint_names = args[0], tuple(args[1:5])
            elif address.startswith("/frond/element/") and address.endswith("/info") and len(args) == 7:
                if not all(isinstance(a, str) for a in args):
                    raise OscError(f"{address[:80]}: names that are not strings")
                e = _element_id(address)  # at most 65,535 elements kept
                self.elements[e] = {"name": args[0], "kind": args[1], "rig": args[2], "joints": tuple(args[3:7])}

    def poll(self, limit=100000):
        frames = []
        for _ in range(limit):
            try:
                data = self.sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                break
            frame = self.take(data)
            if frame is not None:
                frames.append(frame)
        return frames

    def take(self, data):
        """One datagram: its names and field messages kept, its frame returned (None when it
        holds none); a malformed one is counted and changes nothing the frames rely on."""
        try:
            messages = parse_packet(data)
            self.read_names(messages)
            self.fields.read(messages)
            return frame_from_messages(messages) or element_frame_from_messages(messages)
        except (OscError, struct.error, ValueError, UnicodeDecodeError):
            self.malformed += 1
            return None

    def close(self):
        self.sock.close()


# ---------------------------------------------------------------- Blender side

_state = {"receiver": None, "frames": 0, "lost": 0, "last_seq": None, "t0": None, "keyed": 0, "recorded": set(),
          "field_keys": {}, "field_key_bytes": 0, "field_keys_full": False, "errors": 0, "error_said": -1e9}


def _armature(scene):
    obj = scene.frond_receiver.armature
    return obj if obj is not None and obj.type == "ARMATURE" else None


def element_info(element):
    receiver = _state["receiver"]
    return receiver.elements.get(element) if receiver is not None else None


def element_bones(obj, element):
    """The joint sets a secondary element drives: every instance of its kind in frond-gltf's
    naming (`leaf0_joint0` .. `leaf0_joint3`, `leaf1_joint0`, ...; a layer `leaf#2` is a `leaf`),
    as announced by `/frond/element/<e>/info` (kind `layer`)."""
    info = element_info(element)
    if obj is None or info is None or info["kind"] != "layer":
        return []
    kind = info["name"].split("#")[0]
    sets = []
    k = 0
    while all(f"{kind}{k}_joint{j}" in obj.pose.bones for j in range(4)):
        sets.append([f"{kind}{k}_joint{j}" for j in range(4)])
        k += 1
    return sets


def _plant_number(name, prefix):
    """`i` of an element named `PREFIX<i>` or an object named `PREFIX<i>` (zero-padded, with
    Blender's `.001` suffix for a second import), else None."""
    base = name.split(".")[0]
    digits = base[len(prefix):]
    return int(digits) if base.startswith(prefix) and digits.isdigit() else None


def plant_armature(scene, element):
    """The armature a field plant (`plant<i>`, `frond field start`) or graph walker
    (`walker<i>`, `frond walk`) drives: plant i of a field or grove frond-gltf baked, which
    Blender's glTF importer names `<rig>_<i>` with the index zero-padded (`grass_03`)."""
    info = element_info(element)
    if info is None or info["kind"] != "field-plant":
        return None
    i = next((n for n in (_plant_number(info["name"], p) for p in ("plant", "walker")) if n is not None), None)
    if i is None:
        return None
    for obj in scene.objects:
        if obj.type == "ARMATURE" and _plant_number(obj.name, info["rig"] + "_") == i:
            return obj
    return None


def frame_targets(scene, obj, frame, plants):
    """What a frame drives, as (armature, joint sets): the picked armature's main skeleton for
    the global element, a layer's instances in it, or a field plant's own armature. `plants`
    caches `plant_armature` per element for one batch of frames (a lookup scans the scene)."""
    element = frame.get("element", 0)
    if element == 0:
        return [(obj, [bone_names(obj)])] if obj is not None else []
    if element not in plants:
        plants[element] = plant_armature(scene, element)
    plant = plants[element]
    if plant is not None:
        joints = element_info(element)["joints"]
        return [(plant, [[name if name in plant.pose.bones else None for name in joints]])]
    return [(obj, element_bones(obj, element))] if obj is not None else []


def bone_names(obj):
    """The four pose bones frond's joints drive, root first: the announced joint names, else
    `joint0` .. `joint3`, per joint whichever the armature has (None when it has neither)."""
    receiver = _state["receiver"]
    announced = receiver.joint_names if receiver is not None and receiver.joint_names else BONE_NAMES
    names = []
    for name, fallback in zip(announced, BONE_NAMES):
        names.append(name if name in obj.pose.bones else fallback if fallback in obj.pose.bones else None)
    return names


def apply_frame(targets, frame):
    """Sets the pose bones of `targets` (`frame_targets`) from the frame's joint quaternions;
    whether it drove any."""
    driven = False
    for target, sets in targets:
        for names in sets:
            for name, (x, y, z, w) in zip(names, frame["quats"]):
                pb = target.pose.bones.get(name) if name else None
                if pb is None:
                    continue
                pb.rotation_mode = "QUATERNION"
                pb.rotation_quaternion = (w, x, y, z)
                driven = True
    return driven


def key_frame(obj, scene, frame, targets):
    """Keys the bones of `targets` at the frame's device time (see the module docs). An
    armature keyed for the first time in this recording (a field plant's) gets its own new
    action."""
    if _state["t0"] is None:
        _state["t0"] = frame["t"]  # any element's: device time is shared
    fps = scene.render.fps / scene.render.fps_base
    at = scene.frond_receiver.record_start + (frame["t"] - _state["t0"]) * fps
    for target, sets in targets:
        if target.name not in _state["recorded"]:
            _state["recorded"].add(target.name)
            if target is not obj:
                if target.animation_data is None:
                    target.animation_data_create()
                target.animation_data.action = bpy.data.actions.new(f"frond_take_{target.name}")
        for names in sets:
            for name in names:
                pb = target.pose.bones.get(name) if name else None
                if pb is not None:
                    pb.keyframe_insert("rotation_quaternion", frame=at, group=name)
    _state["keyed"] += 1


def whole_fields_on(scene):
    """Whether running fields are evaluated whole (the panel's "Whole fields", on by default)."""
    props = getattr(scene, "frond_receiver", None)
    return props is None or props.whole_fields


def drawn_whole(scene):
    """The elements of announced plants whose field the add-on draws whole: their own poses
    (`/frond/element/<e>/pose`) are skipped, so that one path drives (and keys) each armature.
    Both give the same values: the announced pose is the daemon's evaluation of the plant at
    the field frame's stream time, the add-on's that of the same equations."""
    receiver = _state["receiver"]
    if receiver is None or not whole_fields_on(scene):
        return set()
    return {e for f in receiver.fields.evaluated() if f.targets for e in f.definition.announced}


def process(scene, frames):
    """Applies (and, when recording, keys) received frames; returns how many were applied."""
    obj = _armature(scene)
    plants = {}
    applied = 0
    skip = drawn_whole(scene)
    for frame in frames:
        _state["frames"] += 1
        _state["last_seq"] = frame["seq"]
        if frame["flags"] & DEVICE_LOST:
            _state["lost"] += 1
            continue
        if frame.get("element", 0) in skip:
            continue
        targets = frame_targets(scene, obj, frame, plants)
        if not apply_frame(targets, frame):
            continue
        applied += 1
        # A held frame repeats the previous pose at the same device time: nothing new to key.
        if scene.frond_receiver.recording and not frame["flags"] & HELD:
            key_frame(obj, scene, frame, targets)
    return applied


def field_joint_names(field):
    """The four bone names of a field's rig: as frond-osc sent them for the field, else an
    announced plant's, else the daemon's when the rig is its own, else `joint0` .. `joint3`."""
    if field.joints and all(field.joints):
        return field.joints
    for e in field.definition.announced:
        info = element_info(e)
        if info is not None and all(info["joints"]):
            return info["joints"]
    receiver = _state["receiver"]
    if receiver is not None and receiver.rig == field.definition.rig and receiver.joint_names:
        return receiver.joint_names
    return BONE_NAMES


def field_targets(scene, field):
    """Plant i's armature `<rig>_<i>` (zero-padded, as Blender imports a field GLB frond-gltf
    baked) and its four pose bones, for every plant of `field` in the scene: [(i, armature,
    [pose bone or None] * 4)]. Found again when the scene's objects change."""
    count = len(scene.objects)
    if field.targets is not None and field.scene_objects == count:
        return field.targets
    names = field_joint_names(field)
    prefix = field.definition.rig + "_"
    targets = []
    for obj in scene.objects:
        if obj.type != "ARMATURE" or obj.pose is None:  # no pose before its first evaluation
            continue
        i = _plant_number(obj.name, prefix)
        if i is None or i >= field.definition.plants:
            continue
        bones = [obj.pose.bones.get(n) for n in names]
        for pb in bones:
            if pb is not None:
                pb.rotation_mode = "QUATERNION"
        targets.append((i, obj, bones))
    targets.sort(key=lambda t: t[0])
    field.targets, field.scene_objects = targets, count
    return targets


def plant_placement(field, i):
    """Where frond-gltf's GLB of a field places plant i (`Placement::of_field_plant`), in
    Blender's frame: glTF's (x, 0, z) on the ground is Blender's (x, -z, 0) (its importer turns
    +Y up into +Z up), scaled by the plant's scale."""
    from mathutils import Matrix

    x, z = field.eval.positions[i]
    s = field.scales[i]
    return Matrix.Translation((x, -z, 0.0)) @ Matrix.Diagonal((s, s, s, 1.0))


class BuildError(ValueError):
    """A field's plants cannot be built (no layout yet, no plant to copy)."""


def build_field(scene, field, template=None):
    """Makes the armatures of every plant of `field` that has none in `scene` (`<rig>_<i>`,
    zero-padded as Blender imports frond-gltf's GLB of the field), copied from one plant: the
    armature `template` (default: the field's plant with the lowest number in the scene) and
    the meshes it deforms (its children, and any mesh whose Armature modifier names it), each
    copy's modifier pointed at the copy's armature. A copy stands where the GLB places its
    plant (`plant_placement`), as the template stands at its own plant's place; a template not
    named as a plant of the field counts as standing at the origin at scale 1 (a GLB of one
    plant). Copies share the template's armature and mesh data (each armature has its own
    pose) and go into the template's collection. Returns the armatures made.

    Blender's glTF importer makes a field GLB's plants one operator at a time: about a minute
    for 400 here, and 10,000 did not finish in 14 minutes; copies of one plant take about 2 s
    for 10,000."""
    from mathutils import Matrix

    if field.eval is None or field.scales is None:
        raise BuildError(f"field {field.definition.source}: its layout has not arrived whole yet")
    d = field.definition
    prefix = d.rig + "_"
    have = {}
    for obj in scene.objects:
        i = _plant_number(obj.name, prefix) if obj.type == "ARMATURE" else None
        if i is not None and i < d.plants:
            have.setdefault(i, obj)
    if template is None:
        template = have[min(have)] if have else None
    if template is None or template.type != "ARMATURE":
        raise BuildError(
            f"field {d.source}: no armature of rig {d.rig} to copy: import one plant (frond-gltf bake "
            f"--rig {d.rig}, File > Import > glTF 2.0) and pick it"
        )
    t_index = _plant_number(template.name, prefix)
    own = plant_placement(field, t_index) if t_index is not None and t_index < d.plants else Matrix.Identity(4)
    undo = own.inverted_safe()
    meshes = [o for o in scene.objects if o.type == "MESH" and (o.parent == template or any(
        m.type == "ARMATURE" and m.object == template for m in o.modifiers))]
    collection = template.users_collection[0] if template.users_collection else scene.collection
    digits = len(str(d.plants))
    made = 0
    for i in range(d.plants):
        if i in have:
            continue
        place = plant_placement(field, i) @ undo
        arm = template.copy()
        arm.name = f"{prefix}{i:0{digits}d}"
        arm.animation_data_clear()
        arm.matrix_world = place @ template.matrix_world
        collection.objects.link(arm)
        for mesh in meshes:
            m = mesh.copy()
            m.name = f"{arm.name}_{mesh.name}"
            if mesh.parent == template:
                m.parent = arm  # matrix_parent_inverse copied: it follows the copy as the mesh did
            else:
                m.matrix_world = place @ mesh.matrix_world
            for mod in m.modifiers:
                if mod.type == "ARMATURE" and mod.object == template:
                    mod.object = arm
            collection.objects.link(m)
        made += 1
    field.targets = None
    return made


# Whole-field keys recorded, at most this many bytes (a 10,000-plant field is 640 KB a key).
MAX_RECORD_BYTES = 1 << 30


def drive_fields(scene):
    """Evaluates every plant of each field drawn whole at its newest field frame (the latest
    frame wins: one evaluation an update, however many frames arrived) and sets each plant's
    armature; when recording, keeps the keys (written at `stop_recording`). Returns the plants
    driven."""
    receiver = _state["receiver"]
    if receiver is None or not whole_fields_on(scene):
        return 0
    total = 0
    for field in receiver.fields.evaluated():
        frame = field.frame
        if frame["seq"] == field.drawn_seq:
            continue
        field.drawn_seq = frame["seq"]
        if frame["flags"] & DEVICE_LOST:
            continue
        started = time.perf_counter()
        angles, ok = field.eval.evaluate(frame["tau"])
        quats = joint_quats(angles)
        evaluated = time.perf_counter()
        rows = quats.tolist()
        driven = []
        try:
            for i, _obj, bones in field_targets(scene, field):
                if not ok[i]:
                    continue
                for pb, q in zip(bones, rows[i]):
                    if pb is not None:
                        pb.rotation_quaternion = q
                driven.append(i)
        except ReferenceError:  # an armature was deleted: looked up again next time
            field.targets = None
        field.last_drive = {"seq": frame["seq"], "tau": frame["tau"], "t": frame["t"], "angles": angles,
                            "ok": ok, "driven": len(driven), "evaluate_s": evaluated - started,
                            "drive_s": time.perf_counter() - evaluated}
        total += len(driven)
        if scene.frond_receiver.recording and driven and not frame["flags"] & HELD:
            keep_field_keys(scene, field, frame["t"], quats)
    return total


def keep_field_keys(scene, field, t, quats):
    """Keeps one update's keys of a field drawn whole, at the frame's device time."""
    if _state["t0"] is None:
        _state["t0"] = t
    fps = scene.render.fps / scene.render.fps_base
    at = scene.frond_receiver.record_start + (t - _state["t0"]) * fps
    keys = _state["field_keys"].setdefault(field.id, {"field": field, "at": [], "quats": [], "ok": []})
    if keys["at"] and keys["at"][-1] >= at:
        return  # a frame at a device time already keyed
    size = quats.astype("float32").nbytes
    if _state["field_key_bytes"] + size > MAX_RECORD_BYTES:
        if not _state["field_keys_full"]:
            print(f"frond receiver: whole-field recording stopped at {MAX_RECORD_BYTES >> 20} MiB of keys")
        _state["field_keys_full"] = True
        return
    _state["field_key_bytes"] += size
    keys["at"].append(at)
    keys["quats"].append(quats.astype("float32"))
    keys["ok"].append(field.last_drive["ok"].copy())
    _state["keyed"] += 1


def _fcurves(obj):
    """The F-curves of `obj`'s action: its slot's channel bag (Blender 4.4 and later), else
    the action's own list."""
    ad = obj.animation_data
    try:
        from bpy_extras.anim_utils import action_get_channelbag_for_slot

        bag = action_get_channelbag_for_slot(ad.action, ad.action_slot)
        if bag is not None:
            return bag.fcurves
    except (ImportError, AttributeError):
        pass
    return ad.action.fcurves


def write_field_keys():
    """Writes the kept whole-field keys: each plant armature gets a new action
    (`frond_take_<armature>`, or the one this recording gave it already), its first key by
    `keyframe_insert` (which makes the F-curves wherever this Blender keeps them) and the rest
    added to each F-curve at once."""
    import numpy as np

    for keys in _state["field_keys"].values():
        field = keys["field"]
        if not keys["at"] or field.targets is None:
            continue
        at = np.array(keys["at"])
        quats = np.stack(keys["quats"])  # (m, n, 4, 4)
        ok = np.stack(keys["ok"])  # (m, n)
        for i, obj, bones in field.targets:
            where = np.nonzero(ok[:, i])[0]
            if where.size == 0:
                continue
            try:
                if obj.name not in _state["recorded"]:
                    _state["recorded"].add(obj.name)
                    if obj.animation_data is None:
                        obj.animation_data_create()
                    obj.animation_data.action = bpy.data.actions.new(f"frond_take_{obj.name}")
                first = where[0]
                for pb, q in zip(bones, quats[first, i]):
                    if pb is not None:
                        pb.rotation_quaternion = q.tolist()
                        pb.keyframe_insert("rotation_quaternion", frame=float(at[first]), group=pb.name)
                curves = {(fc.data_path, fc.array_index): fc for fc in _fcurves(obj)}
                for j, pb in enumerate(bones):
                    if pb is None:
                        continue
                    path = pb.path_from_id("rotation_quaternion")
                    for k in range(4):
                        fc = curves.get((path, k))
                        if fc is None or where.size < 2:
                            continue
                        points = fc.keyframe_points
                        had = len(points)
                        points.add(int(where.size - 1))
                        co = np.zeros(2 * len(points), dtype=np.float32)
                        points.foreach_get("co", co)
                        co[2 * had :: 2] = at[where[1:]]
                        co[2 * had + 1 :: 2] = quats[where[1:], i, j, k]
                        points.foreach_set("co", co)
                        fc.update()
            except ReferenceError:
                continue
    _state.update(field_keys={}, field_key_bytes=0)


def poll_once(scene=None):
    """Drains the socket once, applies what arrived and draws the fields evaluated whole;
    what the timer calls (and tests). Returns the frames applied and plants driven."""
    receiver = _state["receiver"]
    if receiver is None:
        return 0
    scene = scene or bpy.context.scene
    applied = process(scene, receiver.poll())
    return applied + drive_fields(scene)


def start(host, port):
    stop()
    _state.update(receiver=Receiver(host, port), frames=0, lost=0, last_seq=None)
    return _state["receiver"].port


def stop():
    if _state["receiver"] is not None:
        _state["receiver"].close()
        _state["receiver"] = None


def start_recording(scene):
    """Starts keying received frames: into a new action on the picked armature (returned; None
    when none is picked) and on every other armature a frame drives (a field plant's), created
    when it is first keyed."""
    obj = _armature(scene)
    action = None
    if obj is not None:
        if obj.animation_data is None:
            obj.animation_data_create()
        action = bpy.data.actions.new("frond_take")
        obj.animation_data.action = action
    props = scene.frond_receiver
    props.record_start = scene.frame_current
    props.recording = True
    _state.update(t0=None, keyed=0, recorded={obj.name} if obj is not None else set(), field_keys={},
                  field_key_bytes=0, field_keys_full=False)
    return action


def stop_recording(scene):
    """Stops keying; the keys of fields drawn whole are written now (`write_field_keys`)."""
    scene.frond_receiver.recording = False
    write_field_keys()


def _timer():
    if _state["receiver"] is None:
        return None
    try:
        poll_once()
    except Exception as e:  # never let a bad frame kill the timer; said at most every 10 s
        _state["errors"] += 1
        now = time.monotonic()
        if now - _state["error_said"] >= 10.0:
            print(f"frond receiver: {e} ({_state['errors']} errors so far)")
            _state["error_said"] = now
    return 1.0 / 120.0


if bpy is not None:

    def _armature_poll(_self, obj):
        return obj.type == "ARMATURE"

    class FrondReceiverProps(bpy.types.PropertyGroup):
        host: bpy.props.StringProperty(name="Host", default="127.0.0.1")
        port: bpy.props.IntProperty(name="Port", default=9000, min=1, max=65535)
        armature: bpy.props.PointerProperty(name="Armature", type=bpy.types.Object, poll=_armature_poll)
        recording: bpy.props.BoolProperty(name="Recording", default=False)
        record_start: bpy.props.FloatProperty(name="Record start frame", default=1.0)
        whole_fields: bpy.props.BoolProperty(
            name="Whole fields",
            description="Evaluate every plant of a running field and drive each plant's armature "
            "(off: only the plants the daemon announces)",
            default=True,
        )

    class FROND_OT_listen(bpy.types.Operator):
        """Listen for frond-osc frames and drive the armature"""

        bl_idname = "frond.listen"
        bl_label = "Listen"

        def execute(self, context):
            props = context.scene.frond_receiver
            try:
                start(props.host, props.port)
            except OSError as e:
                self.report({"ERROR"}, f"cannot listen on {props.host}:{props.port}: {e}")
                return {"CANCELLED"}
            if not bpy.app.timers.is_registered(_timer):
                bpy.app.timers.register(_timer)
            return {"FINISHED"}

    class FROND_OT_stop(bpy.types.Operator):
        """Stop listening"""

        bl_idname = "frond.stop"
        bl_label = "Stop"

        def execute(self, context):
            stop()
            stop_recording(context.scene)
            return {"FINISHED"}

    class FROND_OT_record(bpy.types.Operator):
        """Start or stop keying received frames into a new action"""

        bl_idname = "frond.record"
        bl_label = "Record"

        def execute(self, context):
            scene = context.scene
            if scene.frond_receiver.recording:
                stop_recording(scene)
            elif start_recording(scene) is None:
                self.report({"INFO"}, "no armature picked: recording field plants and walkers only")
            return {"FINISHED"}

    class FROND_OT_build_field(bpy.types.Operator):
        """Make the armature of every plant of the running fields that has none, copied from one
        plant: the field's plant with the lowest number in the scene, else the picked armature"""

        bl_idname = "frond.build_field"
        bl_label = "Build field plants"

        def execute(self, context):
            receiver = _state["receiver"]
            fields = [f for f in receiver.fields.fields.values() if f.eval is not None] if receiver else []
            if not fields:
                self.report({"ERROR"}, "no running field's layout has arrived (Listen, and start frond-osc)")
                return {"CANCELLED"}
            picked = _armature(context.scene)
            made = 0
            for field in fields:
                try:
                    made += build_field(context.scene, field)
                except BuildError as e:
                    if picked is None:
                        self.report({"ERROR"}, str(e))
                        return {"CANCELLED"}
                    made += build_field(context.scene, field, picked)
            self.report({"INFO"}, f"made {made} plants")
            return {"FINISHED"}

    class FROND_PT_panel(bpy.types.Panel):
        bl_label = "frond receiver"
        bl_space_type = "VIEW_3D"
        bl_region_type = "UI"
        bl_category = "frond"

        def draw(self, context):
            props = context.scene.frond_receiver
            col = self.layout.column()
            col.prop(props, "host")
            col.prop(props, "port")
            col.prop(props, "armature")
            if _state["receiver"] is None:
                col.operator("frond.listen", icon="PLAY")
            else:
                col.operator("frond.stop", icon="PAUSE")
                col.label(text=f"frames {_state['frames']}  last seq {_state['last_seq']}")
                receiver = _state["receiver"]
                if receiver.joint_names:
                    col.label(text=f"rig {receiver.rig}: {', '.join(receiver.joint_names)}")
                if _state["lost"]:
                    col.label(text=f"device lost in {_state['lost']} frames", icon="ERROR")
                missing = False  # a field with plants that have no armature yet
                for field in receiver.fields.fields.values():
                    d, drive = field.definition, field.last_drive
                    if drive is None:
                        got = len(field.chunks) if field.eval is None else d.chunks
                        col.label(text=f"field {d.source}: layout {got}/{d.chunks}")
                    else:
                        ms = (drive["evaluate_s"] + drive["drive_s"]) * 1000
                        col.label(text=f"field {d.source}: {drive['driven']}/{d.plants} plants, {ms:.0f} ms")
                    missing = missing or field.eval is not None and (drive is None or drive["driven"] < d.plants)
                if missing:
                    col.operator("frond.build_field", icon="OUTLINER_OB_ARMATURE")
            col.prop(props, "whole_fields")
            label = "Stop recording" if props.recording else "Record"
            col.operator("frond.record", text=label, icon="REC")
            if props.recording:
                col.label(text=f"keyed {_state['keyed']} frames")

    _classes = (FrondReceiverProps, FROND_OT_listen, FROND_OT_stop, FROND_OT_record, FROND_OT_build_field,
                FROND_PT_panel)


def register():
    for cls in _classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.frond_receiver = bpy.props.PointerProperty(type=FrondReceiverProps)


def unregister():
    stop()
    if bpy.app.timers.is_registered(_timer):
        bpy.app.timers.unregister(_timer)
    del bpy.types.Scene.frond_receiver
    for cls in reversed(_classes):
        bpy.utils.unregister_class(cls)
