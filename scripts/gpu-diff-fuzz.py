#!/usr/bin/env python3
"""CPU/GPU differential fuzzing of the example scenes.

Each round takes an example scene, replaces 1-3 of its numbers by values
drawn from a list of awkward ones (zero, tiny, huge, negative), renders the
variant on the CPU and with `--gpu` at a small size, and compares the two
images' mean pixel values. The two back ends answer the same physics, so a
variant both render whose means differ beyond noise is a bug in one of them
(or a refusal that should exist): its scene is kept for a closer look. Also
reported: a render that panics, a warning of non-finite samples, and a
variant that one back end renders and the other refuses without naming a
reason.

This found, on 2026-12-02, the GPU writing an object's quadrics about its
box's centre, which a far support had moved 5000 units from the base (a box
of fireflies), and lights and materials whose values overflow f32 (docs/gpu.md,
"Precision").

usage: scripts/gpu-diff-fuzz.py [--seed N] [--rounds N] [--objects-only]
           [--realtime] [--spp N] [--keep DIR] [--isolux PATH] [--bounds]
           [--cpu-only [--structure]] [--timeout S] [--gpu-flag FLAG ...]
           [--units]

`--gpu-flag=--sorted` (or `--megakernel`, `--f64`) passes a flag to the
GPU's renders only: the CPU against that kernel.

`--bounds` renders each variant on the GPU twice instead, with the render
kernels' indices out of bounds clamped and read as zero (`isolux render
--bounds-probe`, .exr files), and flags a variant whose two images are not
the same byte for byte: a kernel read out of bounds there (docs/gpu.md,
"Probing for indices out of bounds"). Awkward values are what send an
index out of its array. Where the two differ, the clamped render runs
again: if it differs from itself, the driver's wavefront is not
deterministic (Mesa 22.3's lavapipe with random-walk media), and both
probes run again by the megakernel, whose images must then agree.

`--units` rescales the whole scene instead, by a power of ten from 1e-6
to 1e3 (every object under an outer `transform`'s scale, the camera,
lights, `bounds` and `wave` mappings' centres moved with it, point lights'
intensities times the scale squared, media's `scale` divided by it): the
two back ends must agree in any unit. This found, on 2026-12-06, both
back ends' tolerances in units of length that were absolute (docs/gpu.md,
"Scenes in small units").

`--cpu-only --structure` mutates the file's lines instead (deleted,
duplicated, swapped, an array emptied, a number made a string): the
parser must answer each with a file:line:field error or render it.

`--cpu-only` renders on the CPU alone (no adapter needed) with wilder
values besides (1e30, NaN, infinities, 2^32 - 1), and flags a panic, a
non-finite sample or a render past `--timeout` seconds (default 300): a
scene that runs for hours must be refused up front. A render that runs
past the timeout (CPU or GPU) is run once more with three times as long
before it is flagged: lavapipe slows down far more than its share when
other work loads the machine.

Needs Pillow (`apt-get install python3-pil` or `pip install pillow`) and a
release build (`cargo build --release`). The variants are written beside
the examples (so that their relative file names resolve) as `_fuzz.toml`,
removed at the end.
"""

import argparse
import glob
import os
import random
import re
import subprocess
import sys

try:
    from PIL import Image
except ImportError:
    Image = None  # --cpu-only compares no images

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = os.path.join(ROOT, "examples", "scenes")
VALUES = ["0", "1e-6", "1e-3", "0.01", "0.3", "0.999", "2.5", "7", "50",
          "3e3", "1e5", "1e7", "-0.5", "-3"]
# With --cpu-only (no image to compare, so any value goes): also values no
# physical scene holds, which must still be refused or rendered finite.
WILD = ["1e30", "-1e30", "1e-30", "4294967295", "65536", "nan", "inf", "-inf"]
NUMBER = re.compile(r"(?<![\w.])-?\d+(\.\d+)?([eE][-+]?\d+)?(?![\w.])")
OBJECT = re.compile(r"\[\[object\]\](.*?)(?=\n\[\[(?!object\.)|\Z)", re.S)


def mean(path):
    im = Image.open(path).convert("RGB")
    w, h = im.size
    return sum(sum(im.getpixel((x, y))) for y in range(h) for x in range(w)) / (3 * w * h)


def render(isolux, scene, out, gpu, args, probe=None, timeout=None):
    """Renders `scene` to `out`: (exit code, stderr), or (None, why) past
    `timeout` seconds (`args.timeout` by default)."""
    timeout = timeout or args.timeout
    cmd = [isolux, "render", scene, "-o", out, "--quiet", "--width", "32",
           "--height", "24", "--spp", str(args.spp)]
    if gpu:
        cmd.append("--gpu")
        cmd.extend(args.gpu_flag)
    if probe:
        cmd.extend(["--bounds-probe", probe])
    if args.realtime:
        cmd.append("--realtime")
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, f"still running after {timeout:g} s"
    err = "\n".join(l for l in r.stderr.splitlines() if "XDG_RUNTIME_DIR" not in l)
    return r.returncode, err


def same_file(a, b):
    with open(a, "rb") as fa, open(b, "rb") as fb:
        return fa.read() == fb.read()


def probe_again(args, variant, clamp, zero):
    """After the clamped and zero kernels' images differ: the problem to
    flag, or None. A driver whose wavefront is not deterministic (Mesa
    22.3's lavapipe with random-walk media: docs/gpu.md, "The wavefront is
    deterministic: Mesa 22.3's lanes are not") gives two clamped renders
    that differ too; the probe is then run again by the megakernel, which
    is deterministic there, and only a difference between its two probes
    is flagged."""
    again = clamp + ".again.exr"
    r, e = render(args.isolux, variant, again, True, args, "clamp")
    if r != 0:
        return f"the clamped kernels failed on a second run (exit {r}): {e[:300]}"
    if same_file(clamp, again):
        return "the clamped and zero kernels' images differ: a read out of bounds"
    if "--megakernel" in args.gpu_flag:
        return "the megakernel's clamped renders differ from run to run: not deterministic"
    flags = args.gpu_flag
    args.gpu_flag = [f for f in flags if f not in ("--wavefront", "--sorted")] + ["--megakernel"]
    try:
        rc, ec = render(args.isolux, variant, clamp, True, args, "clamp")
        rz, ez = render(args.isolux, variant, zero, True, args, "zero")
    finally:
        args.gpu_flag = flags
    if rc != 0 or rz != 0:
        return f"the megakernel's probes failed (clamp exit {rc}, zero exit {rz}): {(ec + ez)[:300]}"
    if not same_file(clamp, zero):
        return ("the wavefront is not deterministic here, and the megakernel's clamped and "
                "zero images differ: a read out of bounds")
    print("     the wavefront's clamped renders differ from run to run (this driver); "
          "the megakernel's clamped and zero images agree", flush=True)
    return None


def restructure(rng, src):
    """`src` with 1-3 lines deleted, duplicated, swapped, an array
    emptied or a number made a string; and what was done."""
    lines = src.split("\n")
    what = []
    for _ in range(rng.randint(1, 3)):
        op = rng.choice(["deleted", "duplicated", "swapped", "array emptied", "string"])
        i = rng.randrange(len(lines))
        if op == "deleted":
            lines.pop(i)
        elif op == "duplicated":
            lines.insert(i, lines[i])
        elif op == "swapped":
            j = rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == "array emptied":
            lines[i] = re.sub(r"\[[^\[\]]*\]", "[]", lines[i], count=1)
        else:
            lines[i] = re.sub(r"= *-?[0-9][-0-9.e]*", '= "x"', lines[i], count=1)
        what.append(f"line {i + 1}: {op}")
    return "\n".join(lines), what


ARRAY = re.compile(r"\[([^\[\]]*)\]")
NUM = re.compile(r"-?\d+(\.\d+)?([eE][-+]?\d+)?")


def times(text, f):
    """`text` with every number in it multiplied by `f`."""
    return NUM.sub(lambda m: repr(float(m.group(0)) * f), text)


def rescale(src, s):
    """Scene text `src` in units `1 / s` as large: its lengths times `s`
    (objects under an outer `transform`'s scale), point lights'
    intensities times `s^2`, media's `scale` (their coefficients per
    unit) over `s`. The same scene to physics, where the media's
    coefficients are given with a `scale`."""
    out = []
    blocks = re.split(r"(?m)^(?=\[)", src)
    for block in blocks:
        # (A table's header may carry a comment: `[[object]]   # a stone`.)
        header = block.split("\n", 1)[0].split("#", 1)[0].strip()
        lines = block.split("\n")
        kind = re.search(r'(?m)^type\s*=\s*"([a-z_]+)"', block)
        kind = kind.group(1) if kind else ""
        has_transform = any(re.match(r"transform\s*=", l) for l in lines)
        for i, line in enumerate(lines):
            key = line.split("=", 1)[0].strip() if "=" in line else ""
            if header == "[camera]" and key in ("position", "look_at"):
                line = ARRAY.sub(lambda m: "[" + times(m.group(1), s) + "]", line, count=1)
            elif header == "[[light]]" and key == "position":
                line = ARRAY.sub(lambda m: "[" + times(m.group(1), s) + "]", line, count=1)
            elif header == "[[light]]" and key == "intensity":
                line = ARRAY.sub(lambda m: "[" + times(m.group(1), s * s) + "]", line, count=1)
            elif header == "[[object]]" and key == "bounds":
                line = ARRAY.sub(lambda m: "[" + times(m.group(1), s) + "]", line)
            elif header == "[[object]]" and key == "transform":
                # M = T R S: s M = (s T) R (s S) for a uniform s.
                body = line.split("=", 1)[1]
                body = re.sub(r"translate\s*=\s*\[([^\]]*)\]",
                              lambda m: "translate = [" + times(m.group(1), s) + "]", body)
                if re.search(r"scale\s*=", body):
                    body = re.sub(r"scale\s*=\s*(\[[^\]]*\]|[-0-9.eE+]+)",
                                  lambda m: "scale = " + times(m.group(1), s), body)
                else:
                    body = body.replace("{", "{ scale = %r," % s, 1)
                line = "transform =" + body
            elif header == "[[material]]" and kind.startswith("subsurface") and key == "scale":
                line = re.sub(r"=\s*[-0-9.eE+]+", lambda m: "= %r" % (float(m.group(0)[1:]) / s),
                              line, count=1)
            elif header == "[[material]]" and kind == "wave" and key == "center":
                line = ARRAY.sub(lambda m: "[" + times(m.group(1), s) + "]", line, count=1)
            lines[i] = line
        if header == "[[object]]" and not has_transform:
            lines.insert(1, "transform = { scale = %r }" % s)
        out.append("\n".join(lines))
    return "".join(out)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--rounds", type=int, default=40)
    p.add_argument("--objects-only", action="store_true",
                   help="change numbers of [[object]] tables only (geometry)")
    p.add_argument("--realtime", action="store_true", help="compare the real-time mode")
    p.add_argument("--spp", type=int, default=32)
    p.add_argument("--gpu-flag", action="append", default=[], metavar="FLAG",
                   help="a flag for the GPU's renders only, e.g. --gpu-flag=--sorted (repeatable)")
    p.add_argument("--keep", default="/tmp/gpu-diff-fuzz", help="where flagged scenes go")
    p.add_argument("--isolux", default=os.path.join(ROOT, "target", "release", "isolux"))
    p.add_argument("--cpu-only", action="store_true",
                   help="render on the CPU alone, with wilder values; flag crashes and hangs")
    p.add_argument("--structure", action="store_true",
                   help="with --cpu-only: delete, duplicate or swap lines instead of numbers")
    p.add_argument("--timeout", type=float, default=300.0, help="seconds per render")
    p.add_argument("--units", action="store_true",
                   help="rescale the whole scene by a power of ten instead of changing numbers")
    p.add_argument("--bounds", action="store_true",
                   help="render on the GPU with indices out of bounds clamped and read as "
                        "zero; flag images that differ (a read out of bounds)")
    args = p.parse_args()
    if args.bounds and args.cpu_only:
        sys.exit("gpu-diff-fuzz: --bounds renders on the GPU only, --cpu-only on the CPU only")
    if args.structure and not args.cpu_only:
        sys.exit("gpu-diff-fuzz: --structure goes with --cpu-only (most variants are not scenes)")
    values = VALUES + WILD if args.cpu_only else VALUES
    if Image is None and not args.cpu_only and not args.bounds:
        sys.exit("gpu-diff-fuzz: needs Pillow (apt-get install python3-pil, or pip install pillow)")
    if args.realtime:
        args.spp = min(max(args.spp, 4), 25)
    if not os.path.exists(args.isolux):
        sys.exit(f"gpu-diff-fuzz: {args.isolux} not found: cargo build --release")
    os.makedirs(args.keep, exist_ok=True)
    os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")
    rng = random.Random(args.seed)
    scenes = sorted(s for s in glob.glob(os.path.join(SCENES, "*.toml"))
                    if not os.path.basename(s).startswith("_"))
    variant = os.path.join(SCENES, "_fuzz.toml")
    cpu_png, gpu_png = os.path.join(args.keep, "cpu.png"), os.path.join(args.keep, "gpu.png")
    if args.bounds:
        # The two probes' images, in place of the CPU's and the GPU's.
        cpu_png, gpu_png = os.path.join(args.keep, "clamp.exr"), os.path.join(args.keep, "zero.exr")
    flagged = compared = rendered = redone = retried = refused = 0
    try:
        for k in range(args.rounds):
            scene = rng.choice(scenes)
            src = open(scene).read()
            spans = [m.span() for m in OBJECT.finditer(src)] if args.objects_only else [(0, len(src))]
            found = [m for m in NUMBER.finditer(src) if any(a <= m.start() < b for a, b in spans)]
            if not found:
                continue
            what = []
            if args.units:
                e = rng.choice([-6, -5, -4, -3, -2, -1, 1, 2, 3])
                src = rescale(src, 10.0 ** e)
                what = [f"units x1e{e}"]
            elif args.structure:
                src, what = restructure(rng, src)
            else:
                for m in sorted(rng.sample(found, min(len(found), rng.randint(1, 3))),
                                key=lambda m: -m.start()):
                    v = rng.choice(values)
                    line = src.count("\n", 0, m.start()) + 1
                    what.append(f"line {line}: {m.group(0)} -> {v}")
                    src = src[:m.start()] + v + src[m.end():]
            open(variant, "w").write(src)
            name = f"{os.path.basename(scene)} ({'; '.join(what)})"
            # With --bounds both sides are the GPU's, clamped and zero.
            def first(timeout=None):
                if args.bounds:
                    return render(args.isolux, variant, cpu_png, True, args, "clamp", timeout)
                return render(args.isolux, variant, cpu_png, False, args, timeout=timeout)

            def second(timeout=None):
                if args.bounds:
                    return render(args.isolux, variant, gpu_png, True, args, "zero", timeout)
                if args.cpu_only:
                    return 0, ""
                return render(args.isolux, variant, gpu_png, True, args, timeout=timeout)
            (rc, ec), (rg, eg) = first(), second()
            if rc is None or rg is None:
                # Another load on the machine slows lavapipe far more than
                # its share of the cores (its threads wait on each other):
                # seed 383's variant of underwater.toml ran past 300 s on
                # the GPU during a CI run, and in 11 s alone. The side that
                # timed out runs once more with triple the time before a
                # hang is flagged.
                if rc is None:
                    rc, ec = first(3 * args.timeout)
                if rg is None:
                    rg, eg = second(3 * args.timeout)
                retried += 1
            problem = None
            rendered += rc == 0
            if rc is None or rg is None:
                problem = f"hang (CPU {rc}, GPU {rg}): {ec} {eg}"
            elif "panicked" in ec + eg or rc not in (0, 1) or rg not in (0, 1):
                problem = f"crash (CPU {rc}, GPU {rg}): {(ec + eg)[:300]}"
            elif "non-finite" in ec + eg and rc == 0 and rg == 0:
                problem = f"non-finite samples: {(ec + eg)[:300]}"
            elif args.bounds and rc != rg:
                problem = f"clamped exit {rc}, zero exit {rg}: {(ec + eg)[:300]}"
            elif args.bounds and rc == 0:
                compared += 1
                if not same_file(cpu_png, gpu_png):
                    problem = probe_again(args, variant, cpu_png, gpu_png)
                    if problem is None:
                        redone += 1
            elif args.bounds:
                pass  # refused by both, alike
            elif rc == 0 and rg == 1 and "render without --gpu" not in eg \
                    and "does not run on the GPU" not in eg:
                problem = f"the GPU refuses without a reason: {eg[:300]}"
            elif rc == 1 and not ec.strip():
                problem = "the CPU fails without a message"
            elif rc == 0 and rg == 0 and not args.cpu_only:
                compared += 1
                a, b = mean(cpu_png), mean(gpu_png)
                if abs(a - b) > 3 and abs((b + 1) / (a + 1) - 1) > 0.06:
                    problem = f"images differ: mean CPU {a:.1f}, GPU {b:.1f} (of 255)"
                    if "miscompiles the long loops of random walks" in eg:
                        # Mesa 22's known loss of long walks (docs/gpu.md):
                        # still flagged, for a check on another driver.
                        problem += ("; the driver warned of its random walks: rerun on "
                                    "Mesa 25 (scripts/mesa25.sh lvp) before calling it ours")
            both_refused = not args.bounds and rc == 1 and rg == 1
            refused += both_refused and not problem
            if problem:
                flagged += 1
                keep = os.path.join(args.keep, f"flagged-{args.seed}-{k}.toml")
                open(keep, "w").write(src)
                print(f"FLAG {name}: {problem} -> {keep}", flush=True)
            else:
                print(f"ok   {name}{' (refused by both)' if both_refused else ''}", flush=True)
    finally:
        if os.path.exists(variant):
            os.remove(variant)
    slow = f", {retried} rendered again after a timeout" if retried else ""
    if args.cpu_only:
        print(f"{args.rounds} variants, {rendered} rendered (the rest refused){slow}, "
              f"{flagged} flagged")
    else:
        again = f" ({redone} by the megakernel, the wavefront not deterministic here)" if redone else ""
        refusals = f", {refused} refused by both" if refused else ""
        print(f"{compared} variants compared{again}{refusals}{slow}, {flagged} flagged")
    sys.exit(1 if flagged else 0)


if __name__ == "__main__":
    main()
