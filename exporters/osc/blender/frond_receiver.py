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
frond-gltf (`<rig>_<i>`, zero-padded: `grass_03`), so live fields need no armature picked. Every
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
        elif tag in "TF":
            args.append(tag == "T")
        elif tag == "N":
            args.append(None)
        else:
            raise OscError(f"{address}: unsupported type tag {tag!r}")
    return address, args


def parse_packet(data):
    """Returns [(timetag or None, address, args)] for a datagram (bundle or message)."""
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
            for _, address, args in parse_packet(data[i : i + size]):
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
            frame["seq"], frame["t"], frame["angles"] = args[0], args[1], list(args[2:14])
        elif address.startswith("/frond/joint/") and address.endswith("/quat") and len(args) == 4:
            i = int(address.split("/")[3])
            if 0 <= i < 4:
                frame["quats"][i] = tuple(args)
        elif address == "/frond/status" and args:
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
            a = list(args[2:14])
            quats = [joint_quat(*a[3 * j : 3 * j + 3]) for j in range(4)]
            e = int(address.split("/")[3])
            return {"element": e, "timetag": tag, "seq": args[0], "t": args[1], "quats": quats, "flags": 0}
    return None


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
                e = int(address.split("/")[3])
                self.elements[e] = {"name": args[0], "kind": args[1], "rig": args[2], "joints": tuple(args[3:7])}

    def poll(self, limit=100000):
        frames = []
        for _ in range(limit):
            try:
                data = self.sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                break
            try:
                messages = parse_packet(data)
                self.read_names(messages)
                frame = frame_from_messages(messages) or element_frame_from_messages(messages)
            except (OscError, struct.error, ValueError, UnicodeDecodeError):
                self.malformed += 1
                continue
            if frame is not None:
                frames.append(frame)
        return frames

    def close(self):
        self.sock.close()


# ---------------------------------------------------------------- Blender side

_state = {"receiver": None, "frames": 0, "lost": 0, "last_seq": None, "t0": None, "keyed": 0, "recorded": set()}


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


def process(scene, frames):
    """Applies (and, when recording, keys) received frames; returns how many were applied."""
    obj = _armature(scene)
    plants = {}
    applied = 0
    for frame in frames:
        _state["frames"] += 1
        _state["last_seq"] = frame["seq"]
        if frame["flags"] & DEVICE_LOST:
            _state["lost"] += 1
            continue
        targets = frame_targets(scene, obj, frame, plants)
        if not apply_frame(targets, frame):
            continue
        applied += 1
        # A held frame repeats the previous pose at the same device time: nothing new to key.
        if scene.frond_receiver.recording and not frame["flags"] & HELD:
            key_frame(obj, scene, frame, targets)
    return applied


def poll_once(scene=None):
    """Drains the socket once and applies what arrived; what the timer calls (and tests)."""
    receiver = _state["receiver"]
    if receiver is None:
        return 0
    return process(scene or bpy.context.scene, receiver.poll())


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
    _state.update(t0=None, keyed=0, recorded={obj.name} if obj is not None else set())
    return action


def stop_recording(scene):
    scene.frond_receiver.recording = False


def _timer():
    if _state["receiver"] is None:
        return None
    try:
        poll_once()
    except Exception as e:  # never let a bad frame kill the timer
        print(f"frond receiver: {e}")
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
            label = "Stop recording" if props.recording else "Record"
            col.operator("frond.record", text=label, icon="REC")
            if props.recording:
                col.label(text=f"keyed {_state['keyed']} frames")

    _classes = (FrondReceiverProps, FROND_OT_listen, FROND_OT_stop, FROND_OT_record, FROND_PT_panel)


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
