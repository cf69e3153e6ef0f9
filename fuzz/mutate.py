#!/usr/bin/env python3
"""Mutation campaign over the example inputs (issue 14; fuzz/README.md, "Mutation campaign").

Each seed input (robot files, URDFs, a measurement CSV, a mapping file and its export, KRL
.src/.dat/$config.dat, URScript, an XML program, cell files and their meshes) is mutated
(bit flips, truncations, huge and non-finite numbers, binary garbage, very long lines, deleted
and duplicated lines, an empty file) and the `accura` command that reads it runs on each mutant
with a timeout, in a private directory with its own TMPDIR. Every run is checked:

  crash      killed by a signal, or a sanitizer report (AddressSanitizer, UBSan, LeakSanitizer)
  hang       still running after --timeout seconds
  bad-exit   an exit status other than 0 (or the command's other success codes) and 1
  unlocated  exit 1 without a FILE:LINE:COLUMN: message naming one of the inputs (a binary
             mesh: FILE: at byte N:)
  residue    exit 1 and an output written, or a temporary file left (in the run directory or TMPDIR)
  modified   an input file changed

  python3 fuzz/mutate.py --accura build/cli/accura [--per-input 40] [--seed 1] [--timeout 20]
                         [--cases robot,urdf,...] [--keep DIR] [--jobs 2]

Exit status 0 when no run has a finding; the summary gives the counts (mutants, accepted,
rejected, and each kind of finding) and the first findings with their command; --keep DIR keeps
the mutants with findings (each with a .cmd file) for a regression test.
"""
import argparse
import concurrent.futures
import hashlib
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

NUMBERS = [b"1e308", b"-1e308", b"1e-320", b"nan", b"-nan", b"inf", b"-inf", b"-0", b"1e999",
           b"99999999999999999999999", b"0x10", b"", b" ", b"1,5", b"4294967297", b"-2147483649"]
NUMBER_RE = re.compile(rb"(?<![A-Za-z_])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
SANITIZER_RE = re.compile(r"AddressSanitizer|LeakSanitizer|UndefinedBehaviorSanitizer|runtime error:")


def mutate(data: bytes, rng: random.Random, kind: str) -> bytes:
    """One mutant of `data` by `kind` (deterministic for a given rng state)."""
    n = len(data)
    lines = data.split(b"\n")
    if kind == "flip":
        b = bytearray(data)
        for _ in range(rng.randint(1, 4)):
            if b:
                i = rng.randrange(len(b))
                b[i] ^= 1 << rng.randrange(8)
        return bytes(b)
    if kind == "truncate":
        return data[: rng.randrange(n)] if n else data
    if kind == "number":
        spans = [m.span() for m in NUMBER_RE.finditer(data)]
        if not spans:
            return data + rng.choice(NUMBERS)
        out = data
        for a, z in sorted(rng.sample(spans, min(len(spans), rng.randint(1, 2))), reverse=True):
            out = out[:a] + rng.choice(NUMBERS) + out[z:]
        return out
    if kind == "garbage":
        at = rng.randrange(n + 1)
        junk = bytes(rng.randrange(256) for _ in range(rng.randint(1, 64)))
        if rng.random() < 0.5:
            return data[:at] + junk + data[at:]
        return data[:at] + junk + data[at + len(junk):]
    if kind == "longline":
        i = rng.randrange(len(lines))
        filler = rng.choice([b"A", b"9", b" ", b"<a ", b"1,", b"{X 1,"]) * rng.choice([10000, 100000])
        at = rng.randrange(len(lines[i]) + 1)
        lines[i] = lines[i][:at] + filler + lines[i][at:]
        return b"\n".join(lines)
    if kind == "delete":
        if len(lines) > 1:
            del lines[rng.randrange(len(lines))]
        return b"\n".join(lines)
    if kind == "duplicate":
        i = rng.randrange(len(lines))
        lines.insert(i, lines[i])
        return b"\n".join(lines)
    if kind == "swap":
        if len(lines) > 1:
            i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
        return b"\n".join(lines)
    if kind == "empty":
        return b""
    raise ValueError(kind)


KINDS = ["flip", "truncate", "number", "number", "number", "garbage", "longline", "delete",
         "duplicate", "swap"]


class Case:
    """A command reading `files` (name -> source path, copied into the run directory); `target`
    is the one mutated; `argv` uses {name} for the copies' paths and {out} for the output
    directory; `outputs` are written by the command (relative to {out})."""

    def __init__(self, name, files, target, argv, outputs, ok=(0,)):
        self.name, self.files, self.target, self.argv, self.outputs, self.ok = name, files, target, argv, outputs, ok


def cases(seed_dir):
    ex = os.path.join(ROOT, "examples")
    cfg = os.path.join(ex, "$config.dat")
    robots = os.path.join(ROOT, "robots")
    urdf = os.path.join(ROOT, "tests", "data", "urdf")
    cell = os.path.join(ROOT, "tests", "data", "cell")
    out = []
    export = ["export", "--robot", "{robot}", "--format", "robot", "--out", "{out}/model.xml"]
    for r in ["kuka_kr16", "ur10", "scara", "abb_irb120"]:
        out.append(Case("robot:" + r, {"robot": os.path.join(robots, r + ".xml")}, "robot", export, ["model.xml"]))
    out.append(Case("robot:calibrated", {"robot": os.path.join(seed_dir, "calibrated.xml")}, "robot", export, ["model.xml"]))
    for u in ["kr16_2", "ur10", "panda_arm"]:
        out.append(Case("urdf:" + u, {"robot": os.path.join(urdf, u + ".urdf")}, "robot", export, ["model.xml"]))
    identify = ["identify", "--robot", "kuka_kr16", "--data", "{data}", "--out", "{out}/model.xml", "--json", "{out}/s.json", "--quiet"]
    out.append(Case("measurements", {"data": os.path.join(seed_dir, "m.csv")}, "data", identify, ["model.xml", "s.json"]))
    mapped = ["identify", "--robot", "ur10", "--data", "{data}", "--map", "{map}", "--out", "{out}/model.xml", "--quiet"]
    mfiles = {"data": os.path.join(seed_dir, "series_b_head.csv"), "map": os.path.join(ROOT, "docs", "mappings", "ipa_robot_accuracy.map")}
    out.append(Case("mapping:map", mfiles, "map", mapped, ["model.xml"]))
    out.append(Case("mapping:export", mfiles, "data", mapped, ["model.xml"]))
    krl = {"seam.src": os.path.join(ex, "seam.src"), "seam.dat": os.path.join(ex, "seam.dat"), "config": cfg}
    comp = ["compensate", "--robot", "kuka_kr16", "--in", "{seam.src}", "--config", "{config}", "--out", "{out}/comp", "--json", "{out}/r.json"]
    for t in ["seam.src", "seam.dat", "config"]:
        out.append(Case("krl:" + t, krl, t, comp, ["comp", "r.json"]))
    out.append(Case("urscript", {"p.script": os.path.join(ex, "ur10_seam.script")}, "p.script",
                    ["compensate", "--robot", "ur10", "--in", "{p.script}", "--out", "{out}/comp"], ["comp"]))
    out.append(Case("rapid", {"p.mod": os.path.join(ex, "irb120_seam.mod")}, "p.mod",
                    ["compensate", "--robot", "abb_irb120", "--in", "{p.mod}", "--out", "{out}/comp"], ["comp"]))
    out.append(Case("ur_deltas", {"cal": os.path.join(urdf, "ur_forum_calibration.conf")}, "cal",
                    ["export", "--robot", "ur10", "--ur-deltas", "{cal}", "--format", "robot", "--out", "{out}/model.xml"],
                    ["model.xml"]))
    out.append(Case("ur_yaml", {"cal": os.path.join(seed_dir, "ur10_calibration.yaml")}, "cal",
                    ["export", "--robot", "ur10", "--ur-yaml", "{cal}", "--format", "robot", "--out", "{out}/model.xml"],
                    ["model.xml"]))
    two = ["identify", "--robot", "kuka_kr16", "--data", "{data}", "--data", "{data2}", "--out", "{out}/model.xml", "--quiet"]
    out.append(Case("measurements:second_station", {"data": os.path.join(seed_dir, "m.csv"), "data2": os.path.join(seed_dir, "m2.csv")},
                    "data2", two, ["model.xml"]))
    out.append(Case("xml_program", {"p.xml": os.path.join(seed_dir, "seam.xml")}, "p.xml",
                    ["convert", "--in", "{p.xml}", "--out", "{out}/p.src"], ["p.src", "p.dat"]))
    check = ["check", "--robot", "kuka_kr16", "--in", "{seam.src}", "--config", "{config}", "--cell", "{cell.xml}", "--json", "{out}/c.json"]
    cfiles = dict(krl)
    cfiles.update({"cell.xml": os.path.join(ex, "cell", "seam_cell.xml"), "fixture_plate.obj": os.path.join(ex, "cell", "fixture_plate.obj")})
    for t in ["cell.xml", "fixture_plate.obj"]:
        out.append(Case("cell:" + t, cfiles, t, check, ["c.json"], ok=(0, 2)))
    for mesh in ["box_100mm.stl", "post_binary.stl", "box_quads.ply", "plate_m.obj"]:
        files = dict(krl)
        files["cell.xml"] = os.path.join(seed_dir, "cell_" + mesh + ".xml")
        files[mesh] = os.path.join(cell, mesh)
        out.append(Case("mesh:" + mesh, files, mesh, check, ["c.json"], ok=(0, 2)))
    return out


def make_seeds(accura, seed_dir):
    """Inputs the campaign derives with accura itself (fixed seeds)."""
    def run(*argv):
        subprocess.run([accura, *argv], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    run("simulate", "--robot", "kuka_kr16", "--poses", "30", "--seed", "3", "--noise-mm", "0.02", "--effects", "geometric",
        "--out", os.path.join(seed_dir, "m.csv"), "--truth", os.path.join(seed_dir, "truth.xml"))
    run("simulate", "--robot", "kuka_kr16", "--poses", "25", "--seed", "4", "--noise-mm", "0.02", "--effects", "geometric",
        "--out", os.path.join(seed_dir, "m2.csv"), "--truth", os.path.join(seed_dir, "truth2.xml"))
    run("identify", "--robot", "kuka_kr16", "--data", os.path.join(seed_dir, "m.csv"), "--out", os.path.join(seed_dir, "calibrated.xml"), "--quiet")
    run("export", "--robot", "ur10", "--ur-deltas", os.path.join(ROOT, "tests", "data", "urdf", "ur_forum_calibration.conf"),
        "--format", "ur-yaml", "--out", os.path.join(seed_dir, "ur10_calibration.yaml"))
    run("convert", "--in", os.path.join(ROOT, "examples", "seam.src"), "--config", os.path.join(ROOT, "examples", "$config.dat"),
        "--out", os.path.join(seed_dir, "seam.xml"))
    with open(os.path.join(ROOT, "tests", "data", "ipa-robot-accuracy", "series_b_joint_configurations.csv"), "rb") as f:
        head = b"".join(f.readlines()[:41])
    with open(os.path.join(seed_dir, "series_b_head.csv"), "wb") as f:
        f.write(head)
    for mesh in ["box_100mm.stl", "post_binary.stl", "box_quads.ply", "plate_m.obj"]:
        units = "m" if mesh == "plate_m.obj" else "mm"
        with open(os.path.join(seed_dir, "cell_" + mesh + ".xml"), "w") as f:
            f.write('<cell name="c">\n  <object name="o" file="%s" units="%s" x_mm="1500" y_mm="0" z_mm="0"/>\n</cell>\n' % (mesh, units))


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha1(f.read()).hexdigest()


def run_one(accura, case, index, seed, timeout, keep):
    rng = random.Random("%d:%s:%d" % (seed, case.name, index))
    kind = "empty" if index == 0 else rng.choice(KINDS)
    work = tempfile.mkdtemp(prefix="accura_mutate_")
    try:
        inputs = os.path.join(work, "in")
        outdir = os.path.join(work, "out")
        tmp = os.path.join(work, "tmp")
        for d in (inputs, outdir, tmp):
            os.mkdir(d)
        paths = {}
        for name, src in case.files.items():
            dst = os.path.join(inputs, name if "." in name or name == "config" else name + os.path.splitext(src)[1])
            if name == "config":
                dst = os.path.join(inputs, "$config.dat")
            shutil.copyfile(src, dst)
            paths[name] = dst
        with open(case.files[case.target], "rb") as f:
            data = mutate(f.read(), rng, kind)
        with open(paths[case.target], "wb") as f:
            f.write(data)
        before = {p: digest(p) for p in paths.values()}
        def fill(a):
            a = a.replace("{out}", outdir)
            for name, path in paths.items():
                a = a.replace("{" + name + "}", path)
            return a
        argv = [accura] + [fill(a) for a in case.argv]
        env = dict(os.environ, TMPDIR=tmp, ASAN_OPTIONS=os.environ.get("ASAN_OPTIONS", "detect_leaks=1"),
                   UBSAN_OPTIONS=os.environ.get("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1"))
        findings = []
        try:
            proc = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=timeout, env=env,
                                  cwd=work, start_new_session=True)
            rc, err = proc.returncode, proc.stderr.decode("utf-8", "replace")
        except subprocess.TimeoutExpired as e:
            rc, err = None, (e.stderr or b"").decode("utf-8", "replace")
            findings.append("hang")
        outcome = "accepted" if rc in case.ok else "rejected" if rc == 1 else "other"
        if rc is not None:
            if rc < 0 or SANITIZER_RE.search(err):
                findings.append("crash")
            elif rc not in case.ok and rc != 1:
                findings.append("bad-exit")
        if rc == 1 and "crash" not in findings:
            # FILE:LINE:COLUMN, or in a binary mesh FILE: at byte N (fuzz/README.md)
            located = any(re.search(re.escape(p) + r"(:\d+:\d+: |: at byte \d+: )", err) for p in paths.values())
            if not located:
                findings.append("unlocated")
            left = [os.path.join(r, f) for r, _, fs in os.walk(outdir) for f in fs] + os.listdir(tmp)
            left += [f for f in os.listdir(inputs) if os.path.join(inputs, f) not in paths.values()]
            if left:
                findings.append("residue")
        elif rc is not None and "crash" not in findings:
            leftover = os.listdir(tmp) + [f for f in os.listdir(inputs) if os.path.join(inputs, f) not in paths.values()]
            if leftover:
                findings.append("residue")
        if any(os.path.exists(p) and digest(p) != h for p, h in before.items()):
            findings.append("modified")
        record = None
        if findings:
            record = {"case": case.name, "index": index, "kind": kind, "rc": rc, "findings": findings,
                      "cmd": " ".join(argv), "stderr": err.strip().splitlines()[-3:] if err.strip() else []}
            if keep:
                os.makedirs(keep, exist_ok=True)
                base = os.path.join(keep, "%s-%d-%s" % (case.name.replace(":", "_"), index, "+".join(findings)))
                with open(base + os.path.splitext(paths[case.target])[1], "wb") as f:
                    f.write(data)
                with open(base + ".cmd", "w") as f:
                    f.write(" ".join(argv) + "\n" + err)
        return outcome, record
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--accura", default=os.path.join(ROOT, "build", "cli", "accura"))
    ap.add_argument("--per-input", type=int, default=40, help="mutants per case (default 40)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=20, help="seconds per run (default 20)")
    ap.add_argument("--cases", default="", help="comma-separated case name prefixes (default: all)")
    ap.add_argument("--keep", default="", help="directory for the mutants with findings")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    args = ap.parse_args()
    accura = os.path.abspath(args.accura)
    seed_dir = tempfile.mkdtemp(prefix="accura_mutate_seeds_")
    try:
        make_seeds(accura, seed_dir)
        chosen = [c for c in cases(seed_dir) if not args.cases or any(c.name.startswith(p) for p in args.cases.split(","))]
        if args.list:
            for c in chosen:
                print(c.name, " ".join(c.argv))
            return 0
        counts = {"mutants": 0, "accepted": 0, "rejected": 0, "other": 0}
        kinds = {k: 0 for k in ["crash", "hang", "bad-exit", "unlocated", "residue", "modified"]}
        records = []
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            futures = [pool.submit(run_one, accura, c, i, args.seed, args.timeout, args.keep)
                       for c in chosen for i in range(args.per_input)]
            for f in futures:
                outcome, record = f.result()
                counts["mutants"] += 1
                counts[outcome] += 1
                if record:
                    records.append(record)
                    for k in record["findings"]:
                        kinds[k] += 1
        print("cases %d, mutants %d: accepted %d, rejected %d (exit 1), other exit %d" %
              (len(chosen), counts["mutants"], counts["accepted"], counts["rejected"], counts["other"]))
        print("findings: " + ", ".join("%s %d" % kv for kv in kinds.items()))
        for r in records[:40]:
            print("- %s #%d (%s): %s, exit %s: %s" % (r["case"], r["index"], r["kind"], "+".join(r["findings"]), r["rc"],
                                                   " | ".join(r["stderr"])[:300]))
        return 1 if records else 0
    finally:
        shutil.rmtree(seed_dir, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
