#!/usr/bin/env python3
"""frond-hands: a camera's hands as landmark lines for frondd's `webcam` hand source (issue 47).

Reads frames from a camera (V4L2 through OpenCV) or from an image or video file (played in a
loop at --fps, for tests and demos), mirrors each frame left-right (the selfie view, which
MediaPipe's handedness assumes and frond's conversion expects), finds up to --max-hands hands
with MediaPipe Hands (the `mediapipe` wheel 0.10.21, which ships the palm detection and hand
landmark models inside the package: nothing is downloaded at run time) and writes one JSON line
per frame on stdout, the pipe frondd reads:

  {"v":1,"seq":N,"t_us":T,"model_us":M,"w":W,"h":H,"hands":[{"side":"right","score":S,
   "world":[x,y,z, ...63 numbers],"image":[x,y,z, ...63]}]}

`t_us` is the frame's capture time on CLOCK_MONOTONIC (microseconds), `model_us` the model's
time on it. The first line is {"v":1,"hello":"frond-hands",...}; a fatal problem is one line
{"v":1,"error":"..."} and exit status 1. Logs go to stderr.

With --preview PATH it also keeps a small picture of what it sees for the console's camera
panel: the frame as the model saw it (selfie view), scaled to --preview-width, the hands' bones
drawn in green (BGR 0,255,0) and their 21 landmarks in magenta (BGR 255,0,255), a JPEG written
--preview-hz times a second atomically (a temporary file beside it, then a rename) with mode
0640: frondd puts it in its socket directory, which only its own user and group may enter.

Apache-2.0 models and runtime (mediapipe); this script is frond's.
"""

import argparse
import json
import os
import sys
import time

PROTOCOL = 1
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".webp")
# MediaPipe Hands' 21 landmarks joined as bones: the palm and each finger from its base.
BONES = ((0, 1), (1, 2), (2, 3), (3, 4), (0, 5), (5, 6), (6, 7), (7, 8), (5, 9), (9, 10), (10, 11),
         (11, 12), (9, 13), (13, 14), (14, 15), (15, 16), (13, 17), (0, 17), (17, 18), (18, 19), (19, 20))
BONE_BGR = (0, 255, 0)
JOINT_BGR = (255, 0, 255)


def say(obj):
    sys.stdout.write(json.dumps(obj, separators=(",", ":")) + "\n")
    sys.stdout.flush()


def fail(text):
    say({"v": PROTOCOL, "error": text})
    sys.exit(1)


def parse_args(argv):
    p = argparse.ArgumentParser(prog="frond-hands", description=__doc__.split("\n\n")[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--camera", help="a V4L2 device (/dev/video0) or camera index (0)")
    src.add_argument("--file", help="an image or video file, played in a loop at --fps")
    p.add_argument("--fps", type=float, default=30.0, help="frames a second asked of the camera, or played from a file")
    p.add_argument("--width", type=int, default=640, help="frame width asked of the camera")
    p.add_argument("--height", type=int, default=480, help="frame height asked of the camera")
    p.add_argument("--max-hands", type=int, default=2, choices=(1, 2))
    p.add_argument("--complexity", type=int, default=1, choices=(0, 1),
                   help="hand landmark model: 0 lite, 1 full (default)")
    p.add_argument("--frames", type=int, default=0, help="stop after this many frames (0: never)")
    p.add_argument("--static", action="store_true",
                   help="find the hands anew in every frame (no tracking): the same image gives the same landmarks")
    p.add_argument("--preview", help="keep a JPEG of the frame with the hands drawn here (atomically, mode 0640)")
    p.add_argument("--preview-hz", type=float, default=5.0, help="preview pictures a second (0.5 to 30)")
    p.add_argument("--preview-width", type=int, default=320, help="preview width in pixels (64 to 1280)")
    a = p.parse_args(argv)
    if not (0.5 <= a.preview_hz <= 30.0):
        p.error("--preview-hz must be 0.5 to 30")
    if not (64 <= a.preview_width <= 1280):
        p.error("--preview-width must be 64 to 1280")
    if not (1.0 <= a.fps <= 120.0):
        p.error("--fps must be 1 to 120")
    if not (32 <= a.width <= 4096 and 32 <= a.height <= 4096):
        p.error("--width and --height must be 32 to 4096")
    return a


class FileFrames:
    """An image or a video file as an endless stream of frames at `fps`."""

    def __init__(self, cv2, path, fps):
        self.cv2, self.path, self.period = cv2, path, 1.0 / fps
        if not os.path.isfile(path):
            fail(f"{path}: not a regular file")
        self.image = cv2.imread(path) if path.lower().endswith(IMAGE_SUFFIXES) else None
        self.video = None if self.image is not None else cv2.VideoCapture(path)
        if self.image is None and not self.video.isOpened():
            fail(f"{path}: not an image or video OpenCV can read")
        self.next = time.monotonic()

    def read(self):
        delay = self.next - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        self.next = max(self.next + self.period, time.monotonic() - self.period)
        if self.image is not None:
            return self.image.copy()
        ok, frame = self.video.read()
        if not ok:
            self.video.set(self.cv2.CAP_PROP_POS_FRAMES, 0)
            ok, frame = self.video.read()
            if not ok:
                fail(f"{self.path}: no frame could be read")
        return frame


class CameraFrames:
    def __init__(self, cv2, camera, args):
        target = int(camera) if camera.isdigit() else camera
        self.cap = cv2.VideoCapture(target, cv2.CAP_V4L2)
        if not self.cap.isOpened():
            fail(f"cannot open camera {camera} (is it there, and may this user read it? `v4l2-ctl --list-devices`)")
        self.cap.set(cv2.CAP_PROP_FRAME_WIDTH, args.width)
        self.cap.set(cv2.CAP_PROP_FRAME_HEIGHT, args.height)
        self.cap.set(cv2.CAP_PROP_FPS, args.fps)
        self.camera = camera

    def read(self):
        ok, frame = self.cap.read()
        if not ok:
            fail(f"camera {self.camera} stopped giving frames")
        return frame


def flat(landmarks):
    out = []
    for lm in landmarks.landmark:
        out.extend((round(lm.x, 6), round(lm.y, 6), round(lm.z, 6)))
    return out


class Preview:
    """The --preview picture: at most `hz` a second, written whole or not at all."""

    def __init__(self, cv2, path, hz, width):
        self.cv2, self.path, self.period, self.width = cv2, path, 1.0 / hz, width
        self.next = 0.0
        self.failed = False

    def offer(self, rgb, hands):
        now = time.monotonic()
        if now < self.next:
            return
        self.next = now + self.period
        cv2 = self.cv2
        h, w = rgb.shape[:2]
        size = (self.width, max(1, round(h * self.width / w)))
        bgr = cv2.cvtColor(cv2.resize(rgb, size, interpolation=cv2.INTER_AREA), cv2.COLOR_RGB2BGR)
        for image in hands:
            pts = [(round(lm.x * size[0]), round(lm.y * size[1])) for lm in image.landmark]
            for a, b in BONES:
                cv2.line(bgr, pts[a], pts[b], BONE_BGR, 2, cv2.LINE_AA)
            for pt in pts:
                cv2.circle(bgr, pt, 3, JOINT_BGR, -1, cv2.LINE_AA)
        ok, jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 80])
        if ok:
            self.write(jpeg.tobytes())

    def write(self, data):
        tmp = f"{self.path}.{os.getpid()}.tmp"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o640)
            try:
                os.fchmod(fd, 0o640)
                os.write(fd, data)
            finally:
                os.close(fd)
            os.replace(tmp, self.path)
            self.failed = False
        except OSError as e:
            if not self.failed:
                print(f"frond-hands: cannot write the preview {self.path}: {e}", file=sys.stderr)
            self.failed = True


def main(argv):
    args = parse_args(argv)
    try:
        import cv2
        import mediapipe as mp
    except ImportError as e:
        fail(f"the hand model is not installed ({e}): run daemon/device/webcam/install.sh")
    frames = FileFrames(cv2, args.file, args.fps) if args.file else CameraFrames(cv2, args.camera, args)
    hands = mp.solutions.hands.Hands(
        static_image_mode=args.static,
        max_num_hands=args.max_hands,
        model_complexity=args.complexity,
        min_detection_confidence=0.5,
        min_tracking_confidence=0.5,
    )
    say({"v": PROTOCOL, "hello": "frond-hands", "model": f"mediapipe {mp.__version__} hands",
         "complexity": args.complexity, "source": args.file or args.camera})
    preview = Preview(cv2, args.preview, args.preview_hz, args.preview_width) if args.preview else None
    seq = 0
    while args.frames == 0 or seq < args.frames:
        frame = frames.read()
        t_us = time.monotonic_ns() // 1000
        rgb = cv2.cvtColor(cv2.flip(frame, 1), cv2.COLOR_BGR2RGB)
        started = time.perf_counter_ns()
        result = hands.process(rgb)
        model_us = (time.perf_counter_ns() - started) // 1000
        found = []
        if result.multi_hand_landmarks:
            for image, world, side in zip(result.multi_hand_landmarks, result.multi_hand_world_landmarks,
                                          result.multi_handedness):
                c = side.classification[0]
                found.append({"side": c.label.lower(), "score": round(c.score, 4),
                              "world": flat(world), "image": flat(image)})
        if preview:
            preview.offer(rgb, result.multi_hand_landmarks or [])
        h, w = rgb.shape[:2]
        say({"v": PROTOCOL, "seq": seq, "t_us": t_us, "model_us": model_us, "w": w, "h": h, "hands": found})
        seq += 1


if __name__ == "__main__":
    try:
        main(sys.argv[1:])
    except (BrokenPipeError, KeyboardInterrupt):
        # frondd went away or stopped us: nothing left to tell.
        os._exit(0)
