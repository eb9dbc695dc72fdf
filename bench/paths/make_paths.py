#!/usr/bin/env python3
"""Writes the camera paths of the evaluation (format: common/include/afr/common/camera_path.h).

  toycar.path       a fixed close-up view of the BART kitchen's toy car (one key)
  interactive.path  a scripted stand-in for a recorded camera interaction in the kitchen:
                    a viewer standing by the table who looks around in bursts of fast mouse
                    rotation separated by pauses, and takes a few steps; keys at 60 Hz, as a
                    display that records its input each refresh would write them

Run from the repository root:  python3 bench/paths/make_paths.py  (deterministic output).
"""
import math
import os

HEADER = "# afr camera path v1"


def normalize(v):
    n = math.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def quat_from_basis(r, u, b):
    """Unit quaternion (x, y, z, w) of the rotation whose columns are r, u, b."""
    m00, m01, m02 = r[0], u[0], b[0]
    m10, m11, m12 = r[1], u[1], b[1]
    m20, m21, m22 = r[2], u[2], b[2]
    tr = m00 + m11 + m22
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        w, x, y, z = 0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s
    elif m00 > m11 and m00 > m22:
        s = math.sqrt(1.0 + m00 - m11 - m22) * 2
        w, x, y, z = (m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s
    elif m11 > m22:
        s = math.sqrt(1.0 + m11 - m00 - m22) * 2
        w, x, y, z = (m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s
    else:
        s = math.sqrt(1.0 + m22 - m00 - m11) * 2
        w, x, y, z = (m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s
    return normalize([x, y, z, w])


def look_at(eye, target):
    f = normalize([t - e for t, e in zip(target, eye)])
    r = normalize(cross(f, [0.0, 1.0, 0.0]))
    u = cross(r, f)
    return quat_from_basis(r, u, [-c for c in f])


def yaw_pitch(yaw_deg, pitch_deg):
    """Looking along -Z turned by yaw about +Y (positive: to the left), then pitch (up)."""
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    f = [-math.sin(y) * math.cos(p), math.sin(p), -math.cos(y) * math.cos(p)]
    r = normalize(cross(f, [0.0, 1.0, 0.0]))
    u = cross(r, f)
    return quat_from_basis(r, u, [-c for c in f])


def line(t, eye, q, yfov):
    return "%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f %.6f" % (t, *eye, *q, yfov)


def smoothstep(x):
    x = min(1.0, max(0.0, x))
    return x * x * (3 - 2 * x)


def write(name, lines, comment):
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), name)
    with open(path, "w") as f:
        f.write(HEADER + "\n")
        for c in comment:
            f.write("# " + c + "\n")
        f.write("# t ex ey ez qx qy qz qw yfov\n")
        for l in lines:
            f.write(l + "\n")


def toycar():
    eye = [1.55, 0.40, 2.10]
    target = [2.45, 0.04, 1.35]
    write("toycar.path", [line(0.0, eye, look_at(eye, target), math.radians(40.0))],
          ["BART kitchen: a fixed close-up of the toy car driving towards the viewer, t = 11 to 14 s,",
           "eye %s looking at %s, 40 degrees vertical field of view." % (eye, target)])


def interactive():
    # Segments: (duration s, yaw change deg, pitch change deg, eye change m). Each moves with a
    # smoothstep profile (a hand on a mouse speeds up and slows down); zero changes are pauses.
    segments = [
        (1.00, 0, 0, (0, 0, 0)),        # pause
        (0.45, 75, -5, (0, 0, 0)),      # fast turn left (peak ~250 deg/s)
        (0.60, 0, 0, (0, 0, 0)),        # pause
        (0.40, -110, 8, (0, 0, 0)),     # fast turn back right, looking up
        (0.50, 0, 0, (0, 0, 0)),        # pause
        (0.35, 40, -12, (0, 0, 0)),     # quick flick down-left
        (0.80, 0, 0, (0, 0, 0)),        # pause
        (1.20, -30, 6, (0.0, 0, -0.8)), # walk forward while turning slowly
        (0.50, 0, 0, (0, 0, 0)),        # pause
        (0.50, 150, -4, (0, 0, 0)),     # very fast turn (peak ~450 deg/s)
        (0.70, 0, 0, (0, 0, 0)),        # pause
        (0.60, -120, 3, (0.3, 0, 0.3)), # turn back while stepping aside
        (1.00, 0, 0, (0, 0, 0)),        # pause
    ]
    fps = 60
    yaw, pitch, eye = 0.0, -18.0, [2.30, 1.45, 3.05]
    t = 0.0
    lines = [line(t, eye, yaw_pitch(yaw, pitch), math.radians(50.0))]
    for dur, dyaw, dpitch, deye in segments:
        n = int(round(dur * fps))
        y0, p0, e0 = yaw, pitch, list(eye)
        for i in range(1, n + 1):
            s = smoothstep(i / n)
            yaw, pitch = y0 + dyaw * s, p0 + dpitch * s
            eye = [e + d * s for e, d in zip(e0, deye)]
            lines.append(line(t + i / fps, eye, yaw_pitch(yaw, pitch), math.radians(50.0)))
        t += n / fps
    write("interactive.path", lines,
          ["BART kitchen: a scripted stand-in for a recorded interaction (make_paths.py):",
           "pauses and bursts of fast rotation (up to ~450 deg/s) and a few steps; 60 Hz keys."])


if __name__ == "__main__":
    toycar()
    interactive()
