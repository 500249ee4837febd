#!/usr/bin/env python3
"""Fuzzing of the command line: awkward values in every numeric flag.

Each round takes one of the CLI's commands with a valid argument list,
replaces the values of 1-2 of its numeric flags by awkward ones (zero,
negative, tiny, huge, NaN, infinite, not a number at all), runs it, and
checks the guide's promises for bad input:

- no panic (exit status 101, or "panicked" on stderr);
- a failure exits non-zero with a message on stderr and leaves no output
  file behind;
- no run outlives the time limit (a value that would take hours must be
  refused up front, not computed);
- no NaN or infinite value is accepted (no flag means anything by one).

Variants that break a promise are printed with their command line, for a
test to pin. Needs only a release build (`cargo build --release`).

With `--files` it corrupts the input files instead (an example
heightfield read by `wave brdf`, the example sky read by `render`):
truncated, bytes overwritten in the header or anywhere, runs zeroed; the
same promises hold, and a render must not warn of non-finite samples.

usage: scripts/cli-fuzz.py [--seed N] [--rounds N] [--timeout S]
           [--only COMMAND] [--files] [--isolux PATH]
"""

import argparse
import os
import random
import shlex
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = os.path.join(ROOT, "examples", "scenes")
HEIGHTFIELDS = os.path.join(ROOT, "examples", "heightfields")
VALUES = ["0", "-0", "1", "-1", "1e-30", "1e-6", "0.5", "7", "1e4", "1e9",
          "1e30", "4294967295", "18446744073709551616", "nan", "inf", "-inf",
          "x", ""]


def commands(out):
    """(name, fixed arguments, {flag: valid value}, output path)."""
    gallery = os.path.join(SCENES, "gallery.toml")
    sphere = os.path.join(SCENES, "perturbed-sphere.toml")
    grating = os.path.join(HEIGHTFIELDS, "grating.exr")
    return [
        ("render", ["render", sphere, "-o", out + ".png", "--quiet"],
         {"--spp": "1", "--width": "16", "--height": "12", "--seed": "3",
          "--max-depth": "4", "--exposure": "0", "--threads": "2"}, out + ".png"),
        ("render-realtime", ["render", gallery, "-o", out + ".exr", "--quiet", "--realtime"],
         {"--spp": "4", "--width": "16", "--height": "12", "--seed": "3",
          "--exposure": "0"}, out + ".exr"),
        ("brdf-plot", ["brdf", "plot", gallery, "--material", "ggx", "-o", out + ".svg"],
         {"--theta-i": "30", "--phi-i": "0"}, out + ".svg"),
        ("brdf-sphere", ["brdf", "sphere", gallery, "--material", "ward", "-o", out + ".png"],
         {"--size": "16"}, out + ".png"),
        ("sss-profile", ["sss", "profile", "--medium", "skin1", "-o", out + ".svg"],
         {"--scale": "1", "--photons": "2000"}, out + ".svg"),
        ("factor", ["factor", gallery, "--material", "phong", "--no-preview", "-o", out + "_f"],
         {"--res": "8", "--hd-res": "0", "--smoothness": "0.001", "--dynamic-range": "1e-4", "--theta-max": "80",
          "--fit-samples": "4000", "--held-out": "1000", "--svd-rank": "1",
          "--refine": "1", "--seed": "1"}, out + "_f"),
        ("heightfield-noise", ["heightfield", "gen", "--kind", "noise", "-o", out + ".exr"],
         {"--width": "32", "--height": "32", "--texel-um": "0.5", "--rms-um": "0.1",
          "--corr-um": "2", "--seed": "1"}, out + ".exr"),
        ("heightfield-brushed", ["heightfield", "gen", "--kind", "brushed", "-o", out + ".exr"],
         {"--width": "32", "--height": "32", "--texel-um": "0.5", "--rms-um": "0.1",
          "--along-um": "20", "--across-um": "1", "--direction-deg": "10"}, out + ".exr"),
        ("heightfield-scratches", ["heightfield", "gen", "--kind", "scratches", "-o", out + ".exr"],
         {"--width": "32", "--height": "32", "--texel-um": "0.5", "--count": "5",
          "--depth-um": "0.2", "--width-um": "1", "--length-um": "10",
          "--rms-um": "0.05", "--corr-um": "1"}, out + ".exr"),
        ("heightfield-grating", ["heightfield", "gen", "--kind", "grating", "-o", out + ".exr"],
         {"--width": "32", "--height": "32", "--texel-um": "0.5", "--period-um": "2",
          "--amplitude-um": "0.1", "--direction-deg": "0"}, out + ".exr"),
        ("wave-brdf", ["wave", "brdf", "--heightfield", grating, "-o", out + ".exr"],
         {"--texel-um": "0.25", "--vertical-scale": "1", "--center-um": "10,10",
          "--sigma-um": "4", "--incident": "0,0.3,1", "--lambda-um": "0.5",
          "--res": "16"}, out + ".exr"),
        ("wave-brdf-spectral", ["wave", "brdf", "--heightfield", grating, "-o", out + ".exr",
                                "--fresnel", "Ag"],
         {"--center-um": "10,10", "--sigma-um": "3", "--incident": "0.2,0,1",
          "--spectral": "3", "--res": "12"}, out + ".exr"),
        ("bench-geometry", ["bench", "geometry"],
         {"--size": "8", "--bumps": "0,4", "--repeat": "1"}, out + ".none"),
    ]


def corrupted(rng, path):
    """The bytes of `path`, damaged one of four ways, and the way."""
    data = bytearray(open(path, "rb").read())
    how = rng.choice(["truncated", "header", "bytes", "zeroed"])
    if how == "truncated":
        data = data[:rng.randrange(len(data))]
    elif how == "header":
        for _ in range(rng.randint(1, 3)):
            data[rng.randrange(min(len(data), 400))] = rng.randrange(256)
    elif how == "bytes":
        for _ in range(rng.randint(1, 50)):
            data[rng.randrange(len(data))] = rng.randrange(256)
    else:
        i, n = rng.randrange(len(data)), rng.randint(1, 256)
        data[i:i + n] = bytes(len(data[i:i + n]))
    return bytes(data), how


def file_cases(tmp):
    """(name, original, damaged copy, argv, output path)."""
    out = os.path.join(tmp, "out")
    field = os.path.join(tmp, "field.exr")
    sky = os.path.join(tmp, "sky.hdr")
    scene = os.path.join(tmp, "quadrics.toml")
    src = open(os.path.join(SCENES, "quadrics.toml")).read()
    open(scene, "w").write(src.replace('"../env/sky.hdr"', '"' + sky + '"'))
    wave = ["wave", "brdf", "--heightfield", field, "--center-um", "5,5", "--sigma-um", "2",
            "--incident", "0,0.3,1", "--lambda-um", "0.5", "--res", "8", "-o", out + ".exr"]
    render = ["render", scene, "-o", out + ".png", "--width", "16", "--height", "12",
              "--spp", "2", "--quiet"]
    return [
        ("heightfield-brushed", os.path.join(HEIGHTFIELDS, "brushed.exr"), field, wave, out + ".exr"),
        ("heightfield-grating", os.path.join(HEIGHTFIELDS, "grating.exr"), field, wave, out + ".exr"),
        ("environment", os.path.join(ROOT, "examples", "env", "sky.hdr"), sky, render, out + ".png"),
    ]


def verdict(code, err, output, changed, timeout):
    """What the run broke of the promises (module docs): `code` None for
    a run stopped at `timeout`, negative for one killed by a signal;
    `changed` the flags set to awkward values."""
    nonfinite = any(p in ("nan", "inf", "-inf") for v in changed.values() for p in v.split(","))
    if code is None:
        return [f"still running after {timeout:.0f} s"]
    if code == 101 or code < 0 or "panicked" in err:
        return [f"crash (exit {code}): " + (err.strip().splitlines() or [""])[-1]]
    if code == 0:
        if nonfinite:
            return ["accepted a non-finite value"]
        if "non-finite" in err:
            return ["non-finite samples: " + err.strip()[:200]]
        return []
    problems = []
    if not err.strip():
        problems.append(f"exit {code} with nothing on stderr")
    if os.path.exists(output):
        problems.append(f"exit {code} left {output} behind")
    return problems


def run(isolux, argv, timeout):
    try:
        p = subprocess.run([isolux] + argv, capture_output=True, text=True, timeout=timeout)
        return p.returncode, p.stderr
    except subprocess.TimeoutExpired:
        return None, ""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=100)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--only", help="fuzz only the commands whose name starts with this")
    ap.add_argument("--files", action="store_true",
                    help="corrupt the input files (heightfield, environment) instead of flags")
    ap.add_argument("--isolux", default=os.path.join(ROOT, "target", "release", "isolux"))
    args = ap.parse_args()
    if not os.path.exists(args.isolux):
        sys.exit(f"cli-fuzz: no {args.isolux}; run `cargo build --release` first")
    rng = random.Random(args.seed)
    tmp = tempfile.mkdtemp(prefix="isolux-cli-fuzz-")
    out = os.path.join(tmp, "out")
    cmds = [c for c in commands(out) if not args.only or c[0].startswith(args.only)]
    found = 0
    cases = file_cases(tmp) if args.files else None
    # Each command must succeed as given, or its rounds would test nothing.
    for name, *rest in cases or cmds:
        if args.files:
            original, copy, argv, _ = rest
            shutil.copy(original, copy)
        else:
            fixed, flags, _ = rest
            argv = list(fixed) + [f"{f}={v}" for f, v in flags.items()]
        code, err = run(args.isolux, argv, args.timeout)
        if code != 0:
            sys.exit(f"cli-fuzz: {name} fails with its valid values (exit {code}): {err.strip()}")
    for round_ in range(args.rounds):
        if args.files:
            name, original, copy, argv, output = rng.choice(cases)
            data, how = corrupted(rng, original)
            open(copy, "wb").write(data)
            label, changed = f"{name} ({how})", {}
        else:
            name, fixed, flags, output = rng.choice(cmds)
            changed = {}
            for flag in rng.sample(sorted(flags), min(len(flags), rng.choice([1, 1, 2]))):
                v = rng.choice(VALUES)
                if "," in flags[flag] and rng.random() < 0.7:
                    parts = flags[flag].split(",")
                    parts[rng.randrange(len(parts))] = v
                    v = ",".join(parts)
                if v != flags[flag]:
                    changed[flag] = v
            argv = list(fixed) + [f"{f}={changed.get(f, v)}" for f, v in flags.items()]
            label = name + ": " + " ".join(f"{f}={v}" for f, v in changed.items())
        if os.path.isdir(output):
            shutil.rmtree(output)
        elif os.path.exists(output):
            os.remove(output)
        code, err = run(args.isolux, argv, args.timeout)
        problems = verdict(code, err, output, changed, args.timeout)
        short = (err.strip().splitlines() or [""])[-1][:110] if code else ""
        print(f"[{round_:3}] {'BUG' if problems else 'ok'} {label} exit {code} {short}", flush=True)
        if problems:
            found += 1
            if args.files:
                keep = os.path.join(os.getcwd(), f"cli-fuzz-{args.seed}-{round_}" + os.path.splitext(copy)[1])
                open(keep, "wb").write(data)
                problems.append(f"the damaged file: {keep}")
            else:
                problems.append("isolux " + " ".join(shlex.quote(a) for a in argv))
        for p in problems:
            print(f"      {p}", flush=True)
    shutil.rmtree(tmp, ignore_errors=True)
    print(f"cli-fuzz: {args.rounds} rounds, {found} problems")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
