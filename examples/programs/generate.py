#!/usr/bin/env python3
"""Writes the three job-shop part programs of examples/programs/ (LinuxCNC G-code, mm): a pocket with helical entry and
finishing pass, a 2D contour with arcs and corners, a drilling pattern with peck drilling written out as moves. The
programs are kept in the repository; this script documents how they were made (run it to rewrite them)."""
import math
import pathlib

HERE = pathlib.Path(__file__).resolve().parent


def fmt(v):
    text = f"{v:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


class Program:
    def __init__(self, title):
        self.lines = ["%", f"({title})"]
        self.x = self.y = self.z = None

    def add(self, text):
        self.lines.append(text)

    def rapid(self, x=None, y=None, z=None):
        self._move("G0", x, y, z)

    def feed(self, x=None, y=None, z=None, f=None):
        self._move("G1", x, y, z, f)

    def _move(self, code, x, y, z, f=None):
        words = [code]
        for letter, value, attr in (("X", x, "x"), ("Y", y, "y"), ("Z", z, "z")):
            if value is not None:
                words.append(f"{letter}{fmt(value)}")
                setattr(self, attr, value)
        if f is not None:
            words.append(f"F{fmt(f)}")
        self.add(" ".join(words))

    def arc(self, cw, x, y, cx, cy, z=None, f=None):
        words = ["G2" if cw else "G3", f"X{fmt(x)}", f"Y{fmt(y)}"]
        if z is not None:
            words.append(f"Z{fmt(z)}")
            self.z = z
        words += [f"I{fmt(cx - self.x)}", f"J{fmt(cy - self.y)}"]
        if f is not None:
            words.append(f"F{fmt(f)}")
        self.add(" ".join(words))
        self.x, self.y = x, y

    def write(self, name):
        self.add("M30")
        self.add("%")
        (HERE / name).write_text("\n".join(self.lines) + "\n")


def rounded_rectangle(p, cx, cy, a, b, r, f):
    """A closed loop (climb, counter-clockwise) of half-sizes a, b and corner radius r around (cx, cy), from and back
    to the middle of the right side."""
    p.feed(cx + a, cy, f=f)
    corners = [(a - r, b - r, 0), (-(a - r), b - r, 1), (-(a - r), -(b - r), 2), (a - r, -(b - r), 3)]
    for ox, oy, q in corners:
        ang = q * math.pi / 2
        # straight side up to the corner arc, then the arc (90 degrees ccw)
        sx = cx + ox + r * math.cos(ang)
        sy = cy + oy + r * math.sin(ang)
        p.feed(sx, sy)
        ex = cx + ox + r * math.cos(ang + math.pi / 2)
        ey = cy + oy + r * math.sin(ang + math.pi / 2)
        p.arc(False, ex, ey, cx + ox, cy + oy)
    p.feed(cx + a, cy)


def pocket():
    p = Program("pocket 70 x 40 x 6 mm, corner R10, D10 3-flute end mill: helical entry, 3 levels, finishing pass")
    p.add("G17 G21 G40 G49 G80 G90 G94")
    p.add("T1 M6 (D10 end mill, 3 flutes)")
    p.add("S8000 M3")
    p.add("M8")
    cx, cy = 90.0, 55.0
    p.rapid(0, 0, 50)  # clearance
    levels = [-2.0, -4.0, -6.0]
    previous = 0.0
    for level in levels:
        # helical entry on a 3 mm radius, 1 mm per turn, from just above the previous level
        p.rapid(cx + 3, cy)
        p.rapid(z=2)
        p.feed(z=previous + 0.5, f=300)
        z = previous + 0.5
        while z - 1.0 > level:
            z -= 1.0
            p.arc(False, cx + 3, cy, cx, cy, z=z, f=400)
        p.arc(False, cx + 3, cy, cx, cy, z=level, f=400)
        p.arc(False, cx + 3, cy, cx, cy)  # clean the bottom of the helix
        # roughing loops outwards, 4 mm stepover, 0.3 mm left on the walls
        for m in range(4, -1, -1):
            a, b = 34.7 - 4 * m, 19.7 - 4 * m
            rounded_rectangle(p, cx, cy, a, b, max(0.5, 4.7 - 4 * m), 2000)
        p.rapid(z=2)
        previous = level
    # finishing the walls at full depth, climb, with an arc lead-in and lead-out, then a spring pass slower still
    for feed in (250, 180):
        p.rapid(cx + 25, cy)
        p.rapid(z=1)
        p.feed(z=-6, f=300)
        p.arc(False, cx + 35, cy - 0, cx + 30, cy, f=feed)  # lead-in (half circle)
        rounded_rectangle(p, cx, cy, 35.0, 20.0, 5.0, feed)
        p.arc(False, cx + 25, cy, cx + 30, cy)  # lead-out
        p.rapid(z=5)
    p.add("M9")
    p.add("M5")
    p.rapid(0, 0, 50)
    p.write("pocket.ngc")


def contour_path(d):
    """The tool-centre path around the part, offset by d outwards (d = stock left), counter-clockwise from the
    bottom edge: (kind, end x, end y, centre) with kind line, ccw, cw."""
    return [
        ("line", 80, -5 - d, None),
        ("ccw", 95 + d, 10, (80, 10)),
        ("line", 95 + d, 25, None),
        ("cw", 95 + d, 45, (95, 35)),  # notch R10 - d... centred on the edge
        ("line", 95 + d, 60 + d, None),
        ("line", 60 + d * 0.4142, 60 + d, None),
        ("line", 45 + d * 0.4142 - d * 0.4142, 75 + d, None),
        ("line", 10, 75 + d, None),
        ("ccw", -5 - d, 60, (10, 60)),
        ("line", -5 - d, 10, None),
        ("ccw", 10, -5 - d, (10, 10)),
    ]


def contour():
    p = Program("2D contour around a 100 x 80 plate: corners R15, a notch R10, a chamfer; 4 roughing levels in "
                "alternating directions, a slow finishing pass, a spring pass and slow deburring")
    p.add("G17 G21 G40 G49 G80 G90 G94")
    p.add("T2 M6 (D10 end mill, 3 flutes)")
    p.add("S6000 M3")
    levels = [-2.0, -4.0, -6.0, -8.0]
    for n, level in enumerate(levels):
        d = 0.5
        path = contour_path(d)
        p.rapid(-40, -40, 50)  # clear of the vice: a long rapid every pass
        start = (10, -5 - d)
        if n % 2 == 0:
            p.rapid(start[0], start[1] - 10)
            p.rapid(z=2)
            p.feed(z=level, f=400)
            p.feed(start[0], start[1], f=1200)
            for kind, x, y, c in path:
                if kind == "line":
                    p.feed(x, y)
                else:
                    p.arc(kind == "cw", x, y, c[0], c[1])
        else:
            # conventional milling: the same loop backwards (arcs turn the other way)
            p.rapid(start[0], start[1] - 10)
            p.rapid(z=2)
            p.feed(z=level, f=400)
            p.feed(start[0], start[1], f=1000)
            points = [start] + [(x, y) for _, x, y, _ in path]
            for i in range(len(path) - 1, -1, -1):
                kind, _, _, c = path[i]
                x, y = points[i]
                if kind == "line":
                    p.feed(x, y)
                else:
                    p.arc(kind == "ccw", x, y, c[0], c[1])
        p.feed(start[0], start[1] - 10)
        p.rapid(z=5)
    for feed, d in ((250, 0.0), (500, 0.0)):
        path = contour_path(d)
        p.rapid(10, -20)
        p.rapid(z=2)
        p.feed(z=-8, f=300)
        p.arc(False, 10, -5, 10, -12.5, f=feed)  # lead-in half circle
        for kind, x, y, c in path:
            if kind == "line":
                p.feed(x, y)
            else:
                p.arc(kind == "cw", x, y, c[0], c[1])
        p.arc(False, 10, -20, 10, -12.5)
        p.rapid(z=5)
    # deburring the top edge of the chamfer slowly
    p.rapid(60, 60.0)
    p.rapid(z=1)
    p.feed(z=-0.3, f=100)
    p.feed(45, 75, f=60)
    p.feed(60, 60, f=90)
    p.rapid(z=50)
    p.add("M5")
    p.rapid(-40, -40)
    p.write("contour.ngc")


def drilling():
    p = Program("drilling pattern: 7 x 5 holes at 14 x 12 mm, spot drill then peck drilling 8 mm deep")
    p.add("G17 G21 G40 G49 G80 G90 G94")
    holes = []
    for j in range(5):
        row = [(20 + 14 * i, 20 + 12 * j) for i in range(7)]
        holes += row if j % 2 == 0 else row[::-1]
    # spot drilling
    p.add("T3 M6 (spot drill 90 degrees)")
    p.add("S3000 M3")
    p.rapid(0, 0, 50)
    for x, y in holes:
        p.rapid(x, y)
        p.rapid(z=1)
        p.feed(z=-1.5, f=150)
        p.add("G4 P0.2")
        p.rapid(z=1)
    p.rapid(z=50)
    p.add("M5")
    p.rapid(0, 0)  # tool change position
    # peck drilling, written out: feed a peck, rapid out to clear chips, rapid back to just above the last depth
    p.add("T1 M6 (drill D6.8, 2 flutes)")
    p.add("S2500 M3")
    p.add("M8")
    for x, y in holes:
        p.rapid(x, y)
        p.rapid(z=1)
        depth = 0.0
        for peck in (-3.0, -5.5, -8.0):
            if depth < 0:
                p.rapid(z=depth + 0.3)
            p.feed(z=peck, f=180)
            depth = peck
            p.rapid(z=1)
    p.rapid(z=50)
    p.add("M9")
    p.add("M5")
    p.rapid(0, 0)
    p.write("drilling.ngc")


if __name__ == "__main__":
    pocket()
    contour()
    drilling()
