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

Apache-2.0 models and runtime (mediapipe); this script is frond's.
"""

import argparse
import json
import os
import sys
import time

PROTOCOL = 1
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".webp")


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
    a = p.parse_args(argv)
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
        h, w = rgb.shape[:2]
        say({"v": PROTOCOL, "seq": seq, "t_us": t_us, "model_us": model_us, "w": w, "h": h, "hands": found})
        seq += 1


if __name__ == "__main__":
    try:
        main(sys.argv[1:])
    except (BrokenPipeError, KeyboardInterrupt):
        # frondd went away or stopped us: nothing left to tell.
        os._exit(0)
