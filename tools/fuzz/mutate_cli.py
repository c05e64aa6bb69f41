#!/usr/bin/env python3
"""Mutation campaign against the gsd command line (hardening; standard library only).

What it does
  0. With --regressions DIR, first replays DIR/cases.txt (checked-in inputs that once hung or
     crashed, each with its command; tests/data/cli-regressions/), judged as mutants are.
  1. Makes valid seed inputs with the gsd CLI itself (and a few by hand) in WORK/seeds: point
     clouds (.ply binary / ascii / big endian, .xyz, .pc, .obj, .npy), meshes (.obj, .off,
     .stl binary / ascii, .ply), (M,3) query .npy, (N,N,N) grid .npy and its .npy.json
     sidecar, .tori, the TorusNet .safetensors weights (models/torusnet.safetensors), surface
     curves (.txt, .obj `l`) and isolated surface points (.txt).
  2. Checks that every command of the table below succeeds on its unmutated seed.
  3. For every format, writes --count mutants (seeded, reproducible: mutant i of format F
     depends only on --seed, F and i), each with one to three mutations chosen from the
     format's mutator (byte flips/sets, inserted/deleted/duplicated runs, truncation, special
     number tokens, far coordinates (1e30, 1e200, 4294967295, 4e9, ...) on a vertex or point,
     header counts, npy descr/shape/order, STL triangle count, .tori header fields,
     safetensors header length / JSON offsets / dtypes / shapes, out-of-range indices), and
     runs one of the format's commands on it (commands alternate; a share of the runs gets
     --device auto, and commands with BOX get a --bounds box: the unit box, or a tiny
     (1e-3 ... 1e-30), huge, far or thin one), in a fresh empty directory, with a time limit.
     With --minutes, rounds of --block mutants of every format run until the time is up.
  4. A run is a FINDING when it: ran past the time limit (wall clock, or CPU time with
     --cpu-timeout; the process group is killed); died of a signal or
     exited with a status outside gsd's documented set (0 ok, 1 data error, 2 usage error;
     2 is also a finding here because the arguments are always valid); printed a sanitizer
     report / "terminate called" / "Segmentation" / "Aborted"; failed (exit 1) without a
     "gsd: error:" message, or with "out of memory" (an unbounded allocation from a file of at
     most 1 MiB); left any file behind after failing (outputs are atomic); succeeded but an
     expected output is missing or empty, or a stray file (e.g. a temporary) is left; or had a
     peak RSS above --max-rss-mb (ru_maxrss from os.wait4, which includes the RSS of the
     forking Python, ~20 MiB, as a floor; the child is also killed as soon as /proc shows it
     above the limit).
  5. Prints one summary line per format and a total (runs, outcomes, peak RSS, slowest run,
     children's CPU time), then every finding (mutant file, command, exit status, reason, first
     sanitizer / error line, and the command line that regenerates and reruns that one mutant)
     and the distinct findings.
     Exit status: 0 no finding, 1 findings, 2 setup error (a seed or a clean run failed).

Run
  python3 tools/fuzz/mutate_cli.py --gsd build-san/bin/gsd --count 200 --jobs 2 \
      --keep-findings /tmp/gsd-findings
  Options: --count N (mutants per format, 200), --counts NAME=N,... (per format, names or
  prefixes; overrides --count), --minutes M (rounds of --block B mutants per format, 10, until
  M minutes are up), --index I (only mutant I of each format: reproduce a finding; keeps its
  files), --regressions DIR (replay DIR/cases.txt first; --count 0 replays only),
  --timeout S (wall clock, 20), --cpu-timeout S (CPU time; 0: none, else --timeout is only a
  backstop for runs that wait), --seed K (1), --jobs J (1),
  --work DIR (new or empty; default a fresh temp dir, removed when there is no finding),
  --formats a,b (names or prefixes, e.g. cloud,tori; --list-formats shows them),
  --keep-findings DIR (copies each finding's mutant, the seeds and a repro .sh there),
  --max-rss-mb MB (2048), --memory-limit (GSD_MEMORY_LIMIT for the children, 1G),
  --default-device-share F (fraction of runs without `--device cpu`, i.e. --device auto; 0.1),
  -v (one line per run: outcome, mutations, first message), --list-formats.
  Mutants and run directories of clean runs are deleted (regenerate them with the same
  --seed); those of findings are kept.
  Children get ASAN_OPTIONS=detect_leaks=1:abort_on_error=1,
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1, OMP_NUM_THREADS=1, XDG_RUNTIME_DIR=/tmp,
  and LD_PRELOAD=$GSD_KEEP_LOADED when that is set (keeps the Vulkan driver mapped so
  LeakSanitizer does not misreport at exit).
  A finding is reproduced by the printed command, run in an empty directory, or by the
  printed `--index` command line, which regenerates the mutant from its seed.
  CI runs scripts/cli-campaign.sh (seed 1, a fixed count per format); docs/io.md, "Mutation
  campaigns".
"""

import argparse
import concurrent.futures
import json
import math
import os
import random
import re
import shlex
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter, namedtuple
from pathlib import Path

MAX_MUTANT = 1 << 20
REPO = Path(__file__).resolve().parents[2]
MODEL = REPO / "models" / "torusnet.safetensors"
BOUNDS = ["-1", "-1", "-1", "1", "1", "1"]
SANITIZER_MARKERS = [
    "ERROR: AddressSanitizer", "ERROR: LeakSanitizer", "runtime error:",
    "SUMMARY: UndefinedBehaviorSanitizer", "terminate called", "Segmentation", "Aborted",
    "ERROR: ThreadSanitizer", "ERROR: MemorySanitizer",
]
DOCUMENTED_EXITS = {0, 1, 2}

# Replacements for a number token in a text format.
SPECIAL_NUMBERS = [
    "NaN", "nan", "inf", "-inf", "Infinity", "1e308", "-1e308", "1e309", "1e200", "-1e200",
    "1e-320", "1e-45", "0", "-0", "-1", "1", "2147483647", "2147483648", "-2147483649",
    "4294967295", "4294967296", "99999999999", "18446744073709551616", "1e19", "", "-", "+",
    "1e30", "-1e30", "1E+30", "4e9", "-4e9", "4294967295.0", "1e300",
    ".", "1e", "0x1p3", "1,5", "1.5.5", "--1", "3.", ".5", "1" * 400, "abc",
]
# Replacements for an index (faces, curve records, header counts): n is the size at hand.
def index_variants(n):
    return [0, -1, n - 1, n, n + 1, -n, -n - 1, 2 * n, 255, 256, 65535, 65536, 2**31 - 1,
            2**31, 2**32 - 1, 2**32, 2**32 + 1, 2**53, 2**63 - 1, 2**63, 2**64 - 1, 2**64,
            10**20, -(2**31), -(2**63)]
INDEX_JUNK = ["", "x", "1.5", "1e3", "0x10", "+1", "-0", "1/2/3", "1//", "/1", "nan"]
NPY_DESCRS = ["<f4", ">f4", "<f8", ">f8", "<f2", "<i4", "<i8", "|b1", "|u1", "<U3", "|O",
              "<c8", "<f16", "f4", "<f3", "|V24", "", "<f4\x00"]
ST_DTYPES = ["F32", "F16", "BF16", "F64", "I32", "I64", "U8", "BOOL", "F8_E4M3", "f32", "",
             5, None, ["F32"]]
FLOAT_SPECIALS = [math.nan, math.inf, -math.inf, 3.4e38, -3.4e38, 1e30, -0.0, 0.0, 1e-45,
                  1e-38, 1e20, -1e20, -1e30, 4294967295.0, 4e9]
DOUBLE_SPECIALS = [math.nan, math.inf, -math.inf, 1e308, -1e308, 1e200, 0.0, -0.0, 5e-324,
                   1e-320, -1.0, 1e20, 1e-7, 1e30, -1e30, 4294967295.0, 4e9]
# Far but finite coordinates (issue 32: one far vertex made `shm grid --bounds` hang): at the
# ±1e30 gsd accepts, beyond it, 2^32 - 1 (a uint32's maximum read as a coordinate), 4e9.
EXTREME_COORDS = [1e30, -1e30, 1e200, -1e200, 4294967295.0, -4294967295.0, 4e9, 1e15, 1e-30,
                  3.4e38]
EXTREME_FLOAT32 = [x for x in EXTREME_COORDS if abs(x) <= 3.4e38]
EXTREME_TOKENS = [b"1e30", b"-1e30", b"1.0E30", b"1e200", b"-1e200", b"4294967295",
                  b"-4294967295", b"4294967295.0", b"4e9", b"4000000000", b"1e15", b"1e-30",
                  b"1e31", b"9.99e29"]
# --bounds for commands that take one (BOX in a template, or BOX? where it is optional): the
# unit box most often, else tiny boxes (cells down to 1e-31), huge ones, far ones, thin ones.
BOXES = ["0 0 0 1e-3 1e-3 1e-3", "0 0 0 1e-9 1e-9 1e-9", "-1e-30 -1e-30 -1e-30 1e-30 1e-30 1e-30",
         "-1e30 -1e30 -1e30 1e30 1e30 1e30", "4e9 4e9 4e9 4.001e9 4.001e9 4.001e9",
         "-1 -1 -1 1 1 4294967295", "0.1 0.1 0.1 0.1000001 0.1000001 0.1000001",
         "-1e200 -1 -1 1e200 1 1"]


# ----------------------------------------------------------------------------- mutations
# Each operator takes (rng, data: bytes, ctx: dict) and returns new bytes; ctx holds sizes of
# the seed meshes/clouds (for out-of-range indices). An operator that does not apply returns
# the data unchanged; the mutant loop then tries another one.

def op_flip_bits(rng, data, ctx):
    b = bytearray(data)
    for _ in range(rng.randint(1, 8)):
        if b:
            b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
    return bytes(b)


def op_set_bytes(rng, data, ctx):
    b = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        if b:
            b[rng.randrange(len(b))] = rng.choice(
                [0, 0xFF, 0x7F, 0x80, 0x20, 0x0A, 0x0D, ord("-"), ord("9"), ord("#"),
                 rng.randrange(256)])
    return bytes(b)


def op_insert_run(rng, data, ctx):
    pos = rng.randint(0, len(data))
    n = rng.choice([1, 2, 4, 8, rng.randint(1, 64), rng.randint(64, 4096)])
    run = rng.choice([bytes([rng.randrange(256)]) * n, bytes(rng.randrange(256) for _ in range(n)),
                      b"\x00" * n, b" " * n, b"\n" * n, b"9" * n])
    return data[:pos] + run + data[pos:]


def op_delete_run(rng, data, ctx):
    if not data:
        return data
    pos = rng.randrange(len(data))
    n = rng.choice([1, 2, 4, 8, rng.randint(1, 256)])
    return data[:pos] + data[pos + n:]


def op_truncate(rng, data, ctx):
    if not data:
        return data
    head = ctx.get("header_end", 256)  # truncating inside the header is worth more tries
    if rng.random() < 0.5:
        return data[:rng.randrange(min(len(data), head + 1))]
    return data[:rng.randrange(len(data))]


def op_duplicate_chunk(rng, data, ctx):
    if not data:
        return data
    a = rng.randrange(len(data))
    b = min(len(data), a + rng.randint(1, 4096))
    pos = rng.randint(0, len(data))
    return data[:pos] + data[a:b] * rng.choice([1, 1, 2, 16]) + data[pos:]


def op_overwrite_chunk(rng, data, ctx):
    if len(data) < 2:
        return data
    a = rng.randrange(len(data))
    chunk = data[a:a + rng.randint(1, 512)]
    pos = rng.randrange(len(data))
    return data[:pos] + chunk + data[pos + len(chunk):]


BYTE_OPS = [(3, op_flip_bits), (3, op_set_bytes), (2, op_insert_run), (2, op_delete_run),
            (3, op_truncate), (1, op_duplicate_chunk), (1, op_overwrite_chunk)]

# --- text formats

NUMBER_RE = re.compile(rb"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w])")


def _replace_span(data, m, new):
    return data[:m.start()] + new + data[m.end():]


def op_special_number(rng, data, ctx):
    matches = list(NUMBER_RE.finditer(data))
    if not matches:
        return data
    for m in sorted(rng.sample(matches, min(len(matches), rng.choice([1, 1, 1, 2, 5]))),
                    key=lambda m: -m.start()):
        data = _replace_span(data, m, rng.choice(SPECIAL_NUMBERS).encode())
    return data


def _lines(data):
    return data.split(b"\n")


def op_index(rng, data, ctx):
    """An out-of-range / malformed index in a face, polyline, point or curve record."""
    lines = _lines(data)
    keys = (b"f", b"l", b"p", b"v", b"e") if ctx.get("curve") else (b"f", b"l", b"p")
    cand = [i for i, ln in enumerate(lines) if ln.split()[:1] and ln.split()[0] in keys]
    if ctx.get("off_faces"):  # OFF face lines: "3 a b c"
        cand += [i for i, ln in enumerate(lines) if ln.startswith(b"3 ")]
    if not cand:
        return data
    i = rng.choice(cand)
    toks = lines[i].split()
    if len(toks) < 2:
        return data
    j = rng.randrange(1, len(toks)) if not ctx.get("curve") or toks[0] == b"l" else 1
    n = rng.choice(ctx.get("sizes", [100]))
    new = rng.choice(index_variants(n) + INDEX_JUNK)
    toks[j] = str(new).encode()
    lines[i] = b" ".join(toks)
    return b"\n".join(lines)


JUNK_LINES = [b"v 1 2", b"vn 0 0 0", b"f 1", b"f", b"l 1", b"l", b"p", b"#offset 0",
              b"#offset 1", b"#offset 7", b"# offset   0", b"e 1 1.5", b"e 1 -0.5",
              b"f 1 0.7 0.7", b"c 1 2", b"n", b"v -1", b"v 0 0 0 0 0 0 0", b"\t", b"\x00",
              b"\r", b"3 0 0 0", b"1 2 3 4 5 6 7", b"x" * 10000, b"1 " * 5000,
              b"element vertex 1", b"end_header", b"endsolid", b"facet normal 0 0 1",
              b"vertex 0 0 0", b"endloop", b"OFF", b"g group", b"o obj", b"s off"]


def op_line_edit(rng, data, ctx):
    lines = _lines(data)
    if not lines:
        return data
    i = rng.randrange(len(lines))
    kind = rng.choice(["delete", "duplicate", "swap", "junk", "junk", "shuffle_tokens"])
    if kind == "delete":
        del lines[i:i + rng.choice([1, 1, 2, 10])]
    elif kind == "duplicate":
        lines[i:i] = [lines[i]] * rng.choice([1, 1, 3, 100])
    elif kind == "swap":
        j = rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
    elif kind == "junk":
        lines.insert(i, rng.choice(JUNK_LINES))
    else:
        toks = lines[i].split()
        rng.shuffle(toks)
        lines[i] = b" ".join(toks)
    return b"\n".join(lines)


def op_token_count(rng, data, ctx):
    """Drop a token from, or add one to, a line (wrong number of values)."""
    lines = _lines(data)
    cand = [i for i, ln in enumerate(lines) if len(ln.split()) >= 2]
    if not cand:
        return data
    i = rng.choice(cand)
    toks = lines[i].split()
    if rng.random() < 0.5:
        del toks[rng.randrange(1, len(toks))]
    else:
        toks.insert(rng.randrange(1, len(toks) + 1), rng.choice([b"1", b"0", b"0.5", b"x"]))
    lines[i] = b" ".join(toks)
    return b"\n".join(lines)


def op_line_endings(rng, data, ctx):
    return rng.choice([data.replace(b"\n", b"\r\n"), data.replace(b"\n", b"\r"),
                       data.replace(b" ", b"\t"), data.replace(b" ", b",  "),
                       data.rstrip(b"\n"), b"\xef\xbb\xbf" + data, data + b"\x00"])


def op_perturb_number(rng, data, ctx):
    """An awkward value that is still valid: a float zeroed, huge, tiny, negated, nudged or
    copied from elsewhere (degenerate geometry); an integer (index) moved by one or copied."""
    matches = list(NUMBER_RE.finditer(data))
    if not matches:
        return data
    m = rng.choice(matches)
    tok = m.group()
    if tok.lstrip(b"-+").isdigit():
        ints = [x.group() for x in matches if x.group().isdigit()]
        new = rng.choice([str(int(tok) + 1).encode(), str(int(tok) - 1).encode(), b"0",
                          rng.choice(ints) if ints else tok])
        return _replace_span(data, m, new)
    x = float(tok)
    new = rng.choice([0.0, -x, x * (1 + 1e-9), x + 1e-12, x * 1e6, x * 1e-6, 1e29, -1e29, 1e-30,
                      1e15, 1e31, float(rng.choice(matches).group()), rng.choice(EXTREME_COORDS)])
    return _replace_span(data, m, repr(new).encode())


def _is_number(tok):
    try:
        float(tok)
        return True
    except ValueError:
        return False


def op_extreme_coordinate(rng, data, ctx):
    """One vertex (or point) moved far away, or all three of its coordinates: a `v`/`vertex`
    line's x y z, or the first three values of a line of numbers with a decimal point (a cloud
    row, an OFF or ascii PLY vertex)."""
    lines = _lines(data)
    cand = []
    for i, ln in enumerate(lines):
        toks = ln.split()
        if len(toks) >= 4 and toks[0] in (b"v", b"vertex") and all(map(_is_number, toks[1:4])):
            cand.append((i, 1))
        elif len(toks) >= 3 and all(map(_is_number, toks[:3])) and any(
                c in t for t in toks[:3] for c in (b".", b"e", b"E")):
            cand.append((i, 0))
    if not cand:
        return data
    i, first = rng.choice(cand)
    toks = lines[i].split()
    which = [first + rng.randrange(3)] if rng.random() < 0.8 else [first, first + 1, first + 2]
    for j in which:
        toks[j] = rng.choice(EXTREME_TOKENS)
    lines[i] = b" ".join(toks)
    return b"\n".join(lines)


def op_copy_line(rng, data, ctx):
    """A line becomes a copy of another of the same kind: coincident points, duplicate faces."""
    lines = _lines(data)
    kinds = {}
    for i, ln in enumerate(lines):
        toks = ln.split()
        if toks:
            key = toks[0] if toks[0][:1].isalpha() else len(toks)
            kinds.setdefault(key, []).append(i)
    groups = [g for g in kinds.values() if len(g) >= 2]
    if not groups:
        return data
    g = rng.choice(groups)
    i, j = rng.sample(g, 2)
    lines[i] = lines[j]
    return b"\n".join(lines)


def op_degenerate_face(rng, data, ctx):
    """A face or polyline repeats one of its own indices (zero-area face, zero-length piece)."""
    lines = _lines(data)
    cand = [i for i, ln in enumerate(lines)
            if ln[:2] in (b"f ", b"l ") or (ctx.get("off_faces") and ln.startswith(b"3 "))]
    if not cand:
        return data
    i = rng.choice(cand)
    toks = lines[i].split()
    if len(toks) < 3:
        return data
    a, b = rng.sample(range(1, len(toks)), 2)
    toks[a] = toks[b]
    lines[i] = b" ".join(toks)
    return b"\n".join(lines)


TEXT_OPS = [(6, op_special_number), (4, op_perturb_number), (3, op_extreme_coordinate), (2, op_copy_line),
            (2, op_degenerate_face), (3, op_index), (3, op_line_edit), (2, op_token_count),
            (1, op_line_endings)]


def op_off_counts(rng, data, ctx):
    lines = _lines(data)
    for i, ln in enumerate(lines):
        toks = ln.split()
        if i > 0 and len(toks) == 3 and lines[0].strip().upper().endswith(b"OFF"):
            j = rng.randrange(3)
            toks[j] = str(rng.choice(index_variants(int(toks[j]) if toks[j].isdigit() else 1)
                                     + INDEX_JUNK)).encode()
            lines[i] = b" ".join(toks)
            return b"\n".join(lines)
    return data


def op_off_face_arity(rng, data, ctx):
    lines = _lines(data)
    cand = [i for i, ln in enumerate(lines) if ln.startswith(b"3 ")]
    if not cand:
        return data
    i = rng.choice(cand)
    toks = lines[i].split()
    toks[0] = str(rng.choice([0, 1, 2, 4, 255, 100000, -1, 2**32])).encode()
    lines[i] = b" ".join(toks)
    return b"\n".join(lines)


def op_curve_offset(rng, data, ctx):
    """Toggle or break the #offset directive of a curve file."""
    new = rng.choice([b"", b"#offset 1", b"#offset 0", b"#offset", b"#offset 2", b"#offset -1",
                      b"#  offset   0  ", b"#offset 0 0", b"#offsetx 0"])
    if b"#offset 0" in data and rng.random() < 0.7:
        return data.replace(b"#offset 0", new, 1)
    lines = _lines(data)
    lines.insert(rng.randrange(len(lines) + 1), new)
    return b"\n".join(lines)


def op_curve_param(rng, data, ctx):
    """Edge parameter / barycentric weights outside their range."""
    lines = _lines(data)
    cand = [i for i, ln in enumerate(lines) if ln[:2] in (b"e ", b"f ")]
    if not cand:
        return data
    i = rng.choice(cand)
    toks = lines[i].split()
    if len(toks) < 3:
        return data
    j = rng.randrange(2, len(toks))
    toks[j] = rng.choice([b"1.5", b"-0.5", b"-1e-12", b"1.000000001", b"1", b"0", b"0.6",
                          b"nan", b"inf", b"1e-320", b"2"])
    lines[i] = b" ".join(toks)
    return b"\n".join(lines)


# --- PLY

def _ply_split(data):
    k = data.find(b"end_header")
    if k < 0:
        return None
    e = data.find(b"\n", k)
    e = len(data) if e < 0 else e + 1
    return data[:e], data[e:]


def op_ply_count(rng, data, ctx):
    parts = _ply_split(data)
    if not parts:
        return data
    head, body = parts
    ms = list(re.finditer(rb"element (\w+) (\S+)", head))
    if not ms:
        return data
    m = rng.choice(ms)
    n = int(m.group(2)) if m.group(2).isdigit() else 1
    new = str(rng.choice(index_variants(n) + INDEX_JUNK)).encode()
    head = head[:m.start(2)] + new + head[m.end(2):]
    return head + body


PLY_TYPES = [b"char", b"uchar", b"short", b"ushort", b"int", b"uint", b"float", b"double",
             b"int8", b"uint8", b"int16", b"uint16", b"int32", b"uint32", b"float32",
             b"float64", b"long", b"half", b"list uchar int", b"list int int", b"list uchar float",
             b"list float int", b"list uint int"]


def op_ply_header(rng, data, ctx):
    parts = _ply_split(data)
    if not parts:
        return data
    head, body = parts
    lines = head.split(b"\n")
    props = [i for i, ln in enumerate(lines) if ln.startswith(b"property")]
    kind = rng.choice(["type", "type", "format", "delete", "duplicate", "rename", "magic"])
    if kind == "type" and props:
        i = rng.choice(props)
        toks = lines[i].split()
        name = toks[-1]
        lines[i] = b"property " + rng.choice(PLY_TYPES) + b" " + name
    elif kind == "format":
        i = next((i for i, ln in enumerate(lines) if ln.startswith(b"format")), None)
        if i is None:
            return data
        lines[i] = b"format " + rng.choice([b"ascii 1.0", b"binary_little_endian 1.0",
                                             b"binary_big_endian 1.0", b"ascii 2.0", b"binary 1.0",
                                             b"ascii"])
    elif kind in ("delete", "duplicate") and props:
        i = rng.choice(props)
        if kind == "delete":
            del lines[i]
        else:
            lines.insert(i, lines[i])
    elif kind == "rename" and props:
        i = rng.choice(props)
        toks = lines[i].split()
        toks[-1] = rng.choice([b"x", b"y", b"nz", b"vertex_indices", b"vertex_index", b"red",
                               b"X", b""])
        lines[i] = b" ".join(toks)
    else:
        lines[0] = rng.choice([b"ply ", b"PLY", b"ply\r", b""])
    return b"\n".join(lines) + body


PLY_CODES = {"char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h",
             "ushort": "H", "uint16": "H", "int": "i", "int32": "i", "uint": "I", "uint32": "I",
             "float": "f", "float32": "f", "double": "d", "float64": "d"}


def ply_fields(data):
    """[(offset, struct format, element, property, row)] of every value in a binary PLY body
    (list counts appear as property '#count'); None for ascii or unreadable headers."""
    parts = _ply_split(data)
    if not parts:
        return None
    head = parts[0].decode("latin-1")
    endian = ">" if "binary_big_endian" in head else "<" if "binary_little_endian" in head else None
    elements = []
    for ln in head.split("\n"):
        t = ln.split()
        if t[:1] == ["element"] and len(t) == 3 and t[2].isdigit():
            elements.append((t[1], int(t[2]), []))
        elif t[:1] == ["property"] and elements:
            if len(t) == 5 and t[1] == "list" and t[2] in PLY_CODES and t[3] in PLY_CODES:
                elements[-1][2].append((t[4], PLY_CODES[t[2]], PLY_CODES[t[3]]))
            elif len(t) == 3 and t[1] in PLY_CODES:
                elements[-1][2].append((t[2], None, PLY_CODES[t[1]]))
            else:
                return None
    if endian is None:
        return None
    fields, off = [], len(parts[0])
    for name, count, props in elements:
        for row in range(count):
            for prop, count_code, code in props:
                n = 1
                if count_code:
                    fmt = endian + count_code
                    if off + struct.calcsize(fmt) > len(data):
                        return fields
                    n = struct.unpack_from(fmt, data, off)[0]
                    if not isinstance(n, int):  # a float list count (a mutated header)
                        return fields
                    fields.append((off, fmt, name, "#count", row))
                    off += struct.calcsize(fmt)
                for _ in range(max(0, min(n, 1 << 16))):
                    fmt = endian + code
                    if off + struct.calcsize(fmt) > len(data):
                        return fields
                    fields.append((off, fmt, name, prop, row))
                    off += struct.calcsize(fmt)
    return fields


def _pack_value(fmt, value):
    """struct.pack, wrapping integers into the type's range (so 2**40 still makes bytes)."""
    if fmt[-1] == "f" and math.isfinite(value) and abs(value) > 3.4028234e38:
        value = math.copysign(3.4028234e38, value)  # scaled past float32: its largest value
    if fmt[-1] in "fd":
        return struct.pack(fmt, float(value))
    bits = 8 * struct.calcsize(fmt)
    v = int(value) % (1 << bits)
    if fmt[-1].islower() and v >= 1 << (bits - 1):
        v -= 1 << bits
    return struct.pack(fmt, v)


def op_ply_field(rng, data, ctx):
    """A binary PLY value set knowing what it is: coordinates to awkward finite values or a
    copy of another row's, face indices out of range or repeated, list counts changed."""
    fields = ply_fields(data)
    if not fields:
        return data
    b = bytearray(data)
    values = [f for f in fields if f[3] != "#count"]
    for _ in range(rng.choice([1, 1, 2, 4])):
        off, fmt, elem, prop, row = rng.choice(fields if rng.random() < 0.1 else values)
        old = struct.unpack_from(fmt, b, off)[0]
        if prop == "#count":
            new = rng.choice([0, 1, 2, 4, 255, 65535, old + 1, old - 1])
        elif fmt[-1] in "fd":
            same = [f[0] for f in values if f[2] == elem and f[3] == prop]
            other = struct.unpack_from(fmt, b, rng.choice(same))[0]
            far = EXTREME_FLOAT32 if fmt[-1] == "f" else EXTREME_COORDS
            new = rng.choice([other, other, 0.0, -old, old * (1 + 1e-7), 1e-30, 1e3 * old,
                              rng.choice([1e29, -1e29, 1e6 * old]), rng.choice(far)]
                             + ([rng.choice(FLOAT_SPECIALS)] if rng.random() < 0.2 else []))
        else:  # an index: mostly another valid one (a degenerate or rewired face)
            row_vals = [struct.unpack_from(f[1], b, f[0])[0] for f in values
                        if f[2] == elem and f[4] == row and f[3] == prop]
            n = rng.choice(ctx.get("sizes", [100]))
            new = rng.choice(row_vals) if rng.random() < 0.8 else rng.choice(index_variants(n))
        b[off:off + struct.calcsize(fmt)] = _pack_value(fmt, new)
    return bytes(b)


def op_ply_binary_value(rng, data, ctx):
    """A special float in a little/big endian float32 body (4-byte aligned guess)."""
    parts = _ply_split(data)
    if not parts or b"ascii" in parts[0][:40] or len(parts[1]) < 4:
        return data
    head, body = parts
    b = bytearray(body)
    endian = ">" if b"big_endian" in head else "<"
    for _ in range(rng.randint(1, 3)):
        pos = rng.randrange(0, len(b) - 3) & ~3 if rng.random() < 0.7 else rng.randrange(len(b) - 3)
        b[pos:pos + 4] = struct.pack(endian + "f", rng.choice(FLOAT_SPECIALS))
    return head + bytes(b)


def op_ply_body_bytes(rng, data, ctx):
    parts = _ply_split(data)
    if not parts:
        return data
    head, body = parts
    return head + rng.choice([op_flip_bits, op_set_bytes, op_delete_run, op_insert_run])(rng, body, ctx)


PLY_OPS = [(3, op_ply_count), (3, op_ply_header), (1, op_ply_binary_value),
           (2, op_ply_body_bytes)]


# --- STL (binary)

def op_stl_count(rng, data, ctx):
    if len(data) < 84:
        return data
    n = struct.unpack_from("<I", data, 80)[0]
    new = rng.choice([v for v in index_variants(n) if 0 <= v < 2**32] + [0xFFFFFFFF, 0x80000000])
    return data[:80] + struct.pack("<I", new) + data[84:]


def op_stl_header(rng, data, ctx):
    head = rng.choice([b"solid x", b"solid", b"SOLID gsd", b"\x00" * 80, b"solid\nfacet normal"])
    return head + data[len(head):]


def op_stl_value(rng, data, ctx):
    if len(data) < 134:
        return data
    b = bytearray(data)
    n = (len(b) - 84) // 50
    for _ in range(rng.randint(1, 3)):
        t = rng.randrange(n)
        pos = 84 + 50 * t + 4 * rng.randrange(12)
        b[pos:pos + 4] = struct.pack("<f", rng.choice(FLOAT_SPECIALS))
    return bytes(b)


def op_stl_far_vertex(rng, data, ctx):
    """One corner's coordinate (or all three) set to a far value; the same corner of every
    triangle that shares it moves too, so the mesh stays connected through a far vertex."""
    n = (len(data) - 84) // 50
    if n < 1:
        return data
    t, c = 84 + 50 * rng.randrange(n), rng.randrange(3)
    corner = data[t + 12 + 12 * c:t + 24 + 12 * c]
    xyz = list(struct.unpack("<3f", corner))
    for k in ([rng.randrange(3)] if rng.random() < 0.8 else [0, 1, 2]):
        xyz[k] = rng.choice(EXTREME_FLOAT32)
    return data.replace(corner, struct.pack("<3f", *xyz)) if rng.random() < 0.7 else \
        data[:t + 12 + 12 * c] + struct.pack("<3f", *xyz) + data[t + 24 + 12 * c:]


def op_stl_truncate(rng, data, ctx):
    n = max(1, (len(data) - 84) // 50)
    cut = 84 + 50 * rng.randrange(n) + rng.choice([0, 0, 1, 12, 49])
    return data[:cut] if rng.random() < 0.8 else data + b"\x00" * rng.choice([1, 49, 50, 51])


def op_stl_collapse(rng, data, ctx):
    """A triangle corner copied onto another (zero area), or a whole triangle duplicated."""
    n = (len(data) - 84) // 50
    if n < 2:
        return data
    t = 84 + 50 * rng.randrange(n)
    if rng.random() < 0.5:
        a, b = rng.sample(range(3), 2)
        src = data[t + 12 + 12 * a:t + 24 + 12 * a]
        return data[:t + 12 + 12 * b] + src + data[t + 24 + 12 * b:]
    u = 84 + 50 * rng.randrange(n)
    return data[:t] + data[u:u + 50] + data[t + 50:]


STL_OPS = [(4, op_stl_collapse), (4, op_stl_count), (1, op_stl_header), (3, op_stl_value),
           (3, op_stl_far_vertex), (2, op_stl_truncate)]


# --- NPY

def npy_parse(data):
    if not data.startswith(b"\x93NUMPY") or len(data) < 10:
        return None
    major, minor = data[6], data[7]
    if major == 1:
        hlen, start = struct.unpack_from("<H", data, 8)[0], 10
    elif len(data) >= 12:
        hlen, start = struct.unpack_from("<I", data, 8)[0], 12
    else:
        return None
    return major, minor, data[start:start + hlen].decode("latin-1"), data[start + hlen:]


def npy_build(major, minor, header, body, pad=True):
    header = header.rstrip(" \n")
    pre = 10 if major == 1 else 12
    if pad:
        header += " " * ((-(pre + len(header) + 1)) % 64)
    h = (header + "\n").encode("latin-1", "replace")
    fmt = "<H" if major == 1 else "<I"
    n = len(h) if len(h) < (1 << (16 if major == 1 else 32)) else 0
    return b"\x93NUMPY" + bytes([major, minor]) + struct.pack(fmt, n) + h + body


def _npy_edit(rng, data, edit):
    p = npy_parse(data)
    if not p:
        return data
    major, minor, header, body = p
    new_header = edit(header)
    if new_header is None:
        return data
    return npy_build(major, minor, new_header, body, pad=rng.random() < 0.85)


def op_npy_shape_count(rng, data, ctx):
    def edit(h):
        m = re.search(r"'shape':\s*\(([^)]*)\)", h)
        if not m:
            return None
        dims = [d.strip() for d in m.group(1).split(",") if d.strip()]
        if not dims:
            return None
        j = rng.randrange(len(dims))
        n = int(dims[j]) if dims[j].lstrip("-").isdigit() else 1
        dims[j] = str(rng.choice(index_variants(n) + ["1.5", "'8'", "None"]))
        return h[:m.start(1)] + ", ".join(dims) + ("," if len(dims) == 1 else "") + h[m.end(1):]
    return _npy_edit(rng, data, edit)


def op_npy_shape_form(rng, data, ctx):
    def edit(h):
        m = re.search(r"'shape':\s*\(([^)]*)\)", h)
        if not m:
            return None
        dims = [d.strip() for d in m.group(1).split(",") if d.strip()]
        n = int(dims[0]) if dims and dims[0].isdigit() else 8
        forms = ["()", f"({n},)", f"({n}, 1)", f"({n}, 3)", f"({n}, 6)", f"({n}, 6, 1)",
                 f"(1, {n}, 6)", f"({n}, {n})", f"({n}, {n}, {n}, 1)", "(0, 0, 0)", "(0, 3)",
                 "(0, 6)", f"({n * 6},)", f"({n}, 2)", f"({n}, 7)", f"({n}, {n}, {n + 1})",
                 f"({n}, {n}, {n}, 3)", "(4294967296, 4294967296, 1)", "(2, 3", "[8, 8, 8]",
                 "(-8, 8, 8)", "(8, 8, -8)", "(3037000500, 3037000500, 3)"]
        return h[:m.start()] + "'shape': " + rng.choice(forms) + h[m.end():]
    return _npy_edit(rng, data, edit)


def op_npy_descr(rng, data, ctx):
    def edit(h):
        return re.sub(r"'descr':\s*'[^']*'", "'descr': '" + rng.choice(NPY_DESCRS) + "'", h, 1)
    return _npy_edit(rng, data, edit)


def op_npy_dict(rng, data, ctx):
    def edit(h):
        return rng.choice([
            h.replace("False", "True"), h.replace("False", "1"), h.replace("False", "'no'"),
            re.sub(r"'fortran_order':\s*\w+,\s*", "", h),
            re.sub(r"'descr':\s*'[^']*',\s*", "", h),
            re.sub(r"'shape':\s*\([^)]*\),\s*", "", h),
            h.replace("'", '"'), h.replace("}", ""), h.replace("{", ""), "", "{}", "[]",
            h.replace("{", "{'extra': 1, ", 1), h.replace("{", "{'shape': (2, 2), ", 1),
            h.replace("'descr'", "'DESCR'"), h + "\x00", h.replace(" ", ""),
        ])
    return _npy_edit(rng, data, edit)


def op_npy_header_len(rng, data, ctx):
    p = npy_parse(data)
    if not p:
        return data
    major = p[0]
    fmt, lim = ("<H", 0xFFFF) if major == 1 else ("<I", 0xFFFFFFFF)
    n = struct.unpack_from(fmt, data, 8)[0]
    new = rng.choice([0, 1, n - 1, n + 1, n - 16, n + 64, len(data), lim])
    return data[:8] + struct.pack(fmt, max(0, min(lim, new))) + data[8 + struct.calcsize(fmt):]


def op_npy_version(rng, data, ctx):
    p = npy_parse(data)
    if not p:
        return data
    major, minor, header, body = p
    if rng.random() < 0.5:  # a consistent version 2/3 file
        return npy_build(rng.choice([2, 3]), 0, header, body)
    b = bytearray(data)
    b[rng.choice([6, 7])] = rng.choice([0, 2, 3, 4, 9, 255])
    return bytes(b)


def op_npy_value(rng, data, ctx):
    p = npy_parse(data)
    if not p or len(p[3]) < 8:
        return data
    major, minor, header, body = p
    b = bytearray(body)
    wide = "'<f8'" in header
    size = 8 if wide else 4
    for _ in range(rng.choice([1, 1, 2, 8])):
        pos = rng.randrange(len(b) // size) * size
        vals = DOUBLE_SPECIALS if wide else FLOAT_SPECIALS
        b[pos:pos + size] = struct.pack("<d" if wide else "<f", rng.choice(vals))
    return data[:len(data) - len(body)] + bytes(b)


def op_npy_body_size(rng, data, ctx):
    p = npy_parse(data)
    if not p:
        return data
    body = p[3]
    k = rng.choice([1, 3, 4, 8, 12, 24, len(body) // 2, len(body)])
    return data[:len(data) - min(k, len(body))] if rng.random() < 0.6 else data + b"\x00" * k


NPY_OPS = [(3, op_npy_shape_count), (3, op_npy_shape_form), (3, op_npy_descr), (2, op_npy_dict),
           (2, op_npy_header_len), (1, op_npy_version), (3, op_npy_value), (2, op_npy_body_size)]


# --- .tori (64-byte header, N x 15 float64)

def _pack_at(data, fmt, off, value):
    if len(data) < off + struct.calcsize(fmt):
        return data
    return data[:off] + struct.pack(fmt, value) + data[off + struct.calcsize(fmt):]


def op_tori_header(rng, data, ctx):
    if len(data) < 64:
        return data
    n = struct.unpack_from("<Q", data, 16)[0]
    field = rng.choice(["count", "count", "version", "hsize", "h", "fitter", "magic"])
    if field == "count":
        return _pack_at(data, "<Q", 16, rng.choice([v for v in index_variants(n) if 0 <= v < 2**64]))
    if field == "version":
        return _pack_at(data, "<I", 8, rng.choice([0, 2, 0xFFFFFFFF, 0x01000000]))
    if field == "hsize":
        return _pack_at(data, "<I", 12, rng.choice([0, 8, 63, 65, 120, 128, 0xFFFFFFFF]))
    if field == "h":
        return _pack_at(data, "<d", 24, rng.choice(DOUBLE_SPECIALS))
    if field == "fitter":
        name = rng.choice([b"jet", b"net", b"xyz", b"", b"j" * 32, b"\xff" * 32, b"jet\x00junk"])
        return data[:32] + name[:32].ljust(32, b"\x00") + data[64:]
    return rng.choice([b"GSDTORI2", b"gsdtori1", b"GSDTORI", b"\x00" * 8]) + data[8:]


def op_tori_value(rng, data, ctx):
    n = (len(data) - 64) // 120
    if n <= 0:
        return data
    for _ in range(rng.choice([1, 1, 2, 4])):
        rec, field = rng.randrange(n), rng.randrange(15)
        off = 64 + 120 * rec + 8 * field
        old = struct.unpack_from("<d", data, off)[0]
        new = rng.choice(DOUBLE_SPECIALS + [old * (1 + 1e-5), old + 1e-7, -old, old * 1e6])
        data = _pack_at(data, "<d", off, new)
    return data


def op_tori_frame(rng, data, ctx):
    """Break a record's frame: zero normal, s parallel to n, swapped p/n, all zeros."""
    n = (len(data) - 64) // 120
    if n <= 0:
        return data
    off = 64 + 120 * rng.randrange(n)
    rec = list(struct.unpack_from("<15d", data, off))
    kind = rng.randrange(4)
    if kind == 0:
        rec[3:6] = [0.0, 0.0, 0.0]
    elif kind == 1:
        rec[6:9] = rec[3:6]
    elif kind == 2:
        rec[0:3], rec[3:6] = rec[3:6], rec[0:3]
    else:
        rec = [0.0] * 15
    return data[:off] + struct.pack("<15d", *rec) + data[off + 120:]


def op_tori_size(rng, data, ctx):
    k = rng.choice([1, 7, 8, 119, 120, 121, 240])
    return data[:max(0, len(data) - k)] if rng.random() < 0.6 else data + b"\x00" * k


def op_tori_semantic(rng, data, ctx):
    """Still a valid file, awkward numbers: coincident points, a record copied over another,
    flipped normal or tangent (still orthonormal), extreme or zero coefficients, other h."""
    n = (len(data) - 64) // 120
    if n < 2:
        return data
    i, j = rng.sample(range(n), 2)
    oi, oj = 64 + 120 * i, 64 + 120 * j
    rec = list(struct.unpack_from("<15d", data, oi))
    other = list(struct.unpack_from("<15d", data, oj))
    kind = rng.randrange(6)
    if kind == 0:
        rec[0:3] = other[0:3]
    elif kind == 1:
        rec = other
    elif kind == 2:
        rec[3:6] = [-x for x in rec[3:6]]
    elif kind == 3:
        rec[6:9] = [-x for x in rec[6:9]]
    elif kind == 4:
        k = rng.choice([0.0, -1.0, 1e6, 1e-6, 1e150, -1e150])
        rec[9:15] = [x * k for x in rec[9:15]]
    else:
        return _pack_at(data, "<d", 24, rng.choice([1e-9, 1e-3, 0.5, 10.0, 1e6, 1e100]))
    return data[:oi] + struct.pack("<15d", *rec) + data[oi + 120:]


TORI_OPS = [(3, op_tori_header), (2, op_tori_value), (1, op_tori_frame), (2, op_tori_size),
            (5, op_tori_semantic)]


# --- safetensors (u64 header length, JSON header, data)

def st_parse(data):
    if len(data) < 8:
        return None
    n = struct.unpack_from("<Q", data, 0)[0]
    try:
        return json.loads(data[8:8 + n]), data[8 + n:]
    except (ValueError, UnicodeDecodeError):
        return None


def st_build(rng, header, body):
    text = header if isinstance(header, bytes) else json.dumps(header, separators=(",", ":")).encode()
    if rng.random() < 0.3:
        text += b" " * rng.randrange(8)
    n = len(text) if rng.random() < 0.9 else len(text) + rng.choice([-1, 1, 8])
    return struct.pack("<Q", max(0, n)) + text + body


def _st_tensors(header):
    return [k for k in header if k != "__metadata__" and isinstance(header[k], dict)] \
        if isinstance(header, dict) else []


def _on_tensors(op):
    """A mutator of a parsed .safetensors with at least one tensor: op(rng, header, body, data)
    gets the JSON header and the data; any other input comes back unchanged."""
    def wrapped(rng, data, ctx):
        p = st_parse(data)
        if not p or not _st_tensors(p[0]):
            return data
        return op(rng, p[0], p[1], data)
    wrapped.__name__ = op.__name__
    wrapped.__doc__ = op.__doc__
    return wrapped


def op_st_length(rng, data, ctx):
    if len(data) < 8:
        return data
    n = struct.unpack_from("<Q", data, 0)[0]
    new = rng.choice([0, 1, 2, n - 1, n + 1, n + 8, len(data) - 8, len(data), 2**31, 2**32,
                      2**63, 2**64 - 1, 100 * 1024 * 1024])
    return struct.pack("<Q", max(0, min(2**64 - 1, new))) + data[8:]


@_on_tensors
def op_st_offsets(rng, header, body, data):
    names = _st_tensors(header)
    t = header[rng.choice(names)]
    a, b = (t.get("data_offsets") or [0, 0])[:2]
    other = header[rng.choice(names)].get("data_offsets", [0, 0])
    t["data_offsets"] = rng.choice([
        [b, a], [a, b + 4], [a, b - 4], [a, len(body) + 4], [a, 2**64], [a, 2**64 - 1], [-4, b],
        [a + 1, b + 1], [0, 0], [a, a], [a], [a, b, b], ["0", b], [a, 1e20], None, other,
        [a, 2**63], [2**64 - 4, 4], [len(body), len(body) + 4]])
    return st_build(rng, header, body)


@_on_tensors
def op_st_shape(rng, header, body, data):
    t = header[rng.choice(_st_tensors(header))]
    dims = list(t.get("shape") or [1])
    j = rng.randrange(len(dims))
    bumped = dims[:j] + [dims[j] + rng.choice([-1, 1])] + dims[j + 1:]
    t["shape"] = rng.choice([[], [0], dims + [1], dims[:-1], bumped, [2**32, 2**32],
                             [2**31, 2**31, 4], [-1] + dims[1:], [1.5], "abc", None,
                             list(reversed(dims)), [dims[0] * 2] + dims[1:]])
    return st_build(rng, header, body)


@_on_tensors
def op_st_dtype(rng, header, body, data):
    header[rng.choice(_st_tensors(header))]["dtype"] = rng.choice(ST_DTYPES)
    return st_build(rng, header, body)


@_on_tensors
def op_st_entries(rng, header, body, data):
    names = _st_tensors(header)
    name = rng.choice(names)
    kind = rng.randrange(6)
    if kind == 0:
        del header[name]
    elif kind == 1:
        header[name + "x"] = header.pop(name)
    elif kind == 2:
        header["__metadata__"] = rng.choice([{"format": "pt"}, {"a": 1}, [], "x", None])
    elif kind == 3:
        header["extra"] = {"dtype": "F32", "shape": [4], "data_offsets": [len(body), len(body) + 16]}
    elif kind == 4:
        header[name] = rng.choice([[], "x", 1, None, {}])
    else:  # a duplicated key: only expressible in the text
        text = json.dumps(header, separators=(",", ":"))
        entry = '"%s":%s' % (name, json.dumps(header[names[0]], separators=(",", ":")))
        return st_build(rng, ("{" + entry + "," + text[1:]).encode(), body)
    return st_build(rng, header, body)


def op_st_json_text(rng, data, ctx):
    if len(data) < 8:
        return data
    n = struct.unpack_from("<Q", data, 0)[0]
    text, body = data[8:8 + n], data[8 + n:]
    if rng.random() < 0.3:
        new = rng.choice([b"", b"[]", b"null", b"{", b"{}", b"1", b'"x"', text[:len(text) // 2],
                          text.replace(b"{", b"[", 1), text + b"}"])
    else:
        new = op_special_number(rng, text, ctx)
    return st_build(rng, new, body)


def op_st_value(rng, data, ctx):
    p = st_parse(data)
    if not p or len(p[1]) < 4:
        return data
    body = bytearray(p[1])
    for _ in range(rng.choice([1, 1, 4, 64])):
        pos = rng.randrange(len(body) // 4) * 4
        body[pos:pos + 4] = struct.pack("<f", rng.choice(FLOAT_SPECIALS))
    return data[:len(data) - len(body)] + bytes(body)


@_on_tensors
def op_st_tensor(rng, header, body, data):
    """Still a valid file, other weights: a tensor scaled (0, -1, 1e3, ...) or two
    same-sized tensors' data swapped."""
    def span(t):  # a tensor's (begin, end) when it is F32 data inside the body, else None
        o = t.get("data_offsets")
        ok = (t.get("dtype") == "F32" and isinstance(o, list) and len(o) == 2
              and all(type(x) is int for x in o) and 0 <= o[0] <= o[1] <= len(body)
              and (o[1] - o[0]) % 4 == 0)
        return tuple(o) if ok else None
    spans = [sp for sp in (span(header[k]) for k in _st_tensors(header)) if sp]
    if not spans:
        return data
    a, b = rng.choice(spans)
    body = bytearray(body)
    same = [sp for sp in spans if sp[1] - sp[0] == b - a and sp != (a, b)]
    if same and rng.random() < 0.3:
        c, d = rng.choice(same)
        body[a:b], body[c:d] = body[c:d], body[a:b]
    else:
        k = rng.choice([0.0, -1.0, 1e3, 1e-3, 1e30, 1e-30])
        vals = struct.unpack_from("<%df" % ((b - a) // 4), body, a)
        scaled = [max(-3.4e38, min(3.4e38, v * k)) for v in vals]
        body[a:b] = struct.pack("<%df" % len(scaled), *scaled)
    return data[:len(data) - len(body)] + bytes(body)


ST_OPS = [(6, op_st_tensor), (2, op_st_length), (4, op_st_offsets), (3, op_st_shape), (2, op_st_dtype),
          (3, op_st_entries), (2, op_st_json_text), (2, op_st_value)]

# Mutator kinds: weighted operator lists (byte-level operators everywhere, less often).
def _scaled(ops, k):
    return [(w * k, f) for w, f in ops]


MUTATORS = {
    "text": TEXT_OPS + _scaled(BYTE_OPS, 0.3),
    "off": TEXT_OPS + [(2, op_off_counts), (2, op_off_face_arity)] + _scaled(BYTE_OPS, 0.3),
    "curve": TEXT_OPS + [(2, op_curve_offset), (3, op_curve_param)] + _scaled(BYTE_OPS, 0.3),
    "ply-text": PLY_OPS + TEXT_OPS + _scaled(BYTE_OPS, 0.3),
    "ply-binary": PLY_OPS + [(10, op_ply_field)] + _scaled(BYTE_OPS, 0.5),
    "stl": STL_OPS + _scaled(BYTE_OPS, 0.5),
    "npy": NPY_OPS + _scaled(BYTE_OPS, 0.5),
    "tori": TORI_OPS + _scaled(BYTE_OPS, 0.5),
    "safetensors": ST_OPS + _scaled(BYTE_OPS, 0.3),
}


MUTATOR_ERRORS = Counter()
MUTATOR_LOCK = threading.Lock()


def mutate(seed_data, kind, ctx, rng):
    """One to three mutations; returns (data, names of the operators applied)."""
    ops = MUTATORS[kind]
    weights = [w for w, _ in ops]
    data, names = seed_data, []
    for _ in range(rng.choices([1, 2, 3], [0.6, 0.25, 0.15])[0]):
        for _attempt in range(8):  # retry operators that do not apply to this data
            op = rng.choices([f for _, f in ops], weights)[0]
            try:
                new = op(rng, data, ctx)[:MAX_MUTANT]
            except Exception as e:  # an operator's bug on odd data: skipped, counted, reported
                with MUTATOR_LOCK:
                    MUTATOR_ERRORS[f"{op.__name__}: {type(e).__name__}: {e}"[:160]] += 1
                continue
            if new != data:
                data = new
                names.append(op.__name__[3:])
                break
    if data == seed_data:  # never run the seed itself
        data = op_flip_bits(rng, data, ctx)
        names.append("flip_bits")
    return data, names


# ----------------------------------------------------------------------------- seeds

def gsd_seed(gsd, seeds, *args):
    r = subprocess.run([gsd, "-q", *args], cwd=seeds, env=child_env(None),
                       capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        raise SystemExit(f"setup: `gsd {' '.join(args)}` failed ({r.returncode}): {r.stderr.strip()}")


def read_obj_mesh(path):
    verts, faces = [], []
    for ln in path.read_text().splitlines():
        t = ln.split()
        if t[:1] == ["v"]:
            verts.append(tuple(map(float, t[1:4])))
        elif t[:1] == ["f"]:
            faces.append([int(x.split("/")[0]) - 1 for x in t[1:]])
    return verts, faces


def read_xyz_cloud(path):
    return [tuple(map(float, ln.split()[:6])) for ln in path.read_text().splitlines()
            if ln.strip() and not ln.startswith("#")]


def vertex_ring(faces, v):
    """The oriented link of vertex v (its neighbours in order), for a closed triangle mesh."""
    nxt = {}
    for f in faces:
        if v in f:
            i = f.index(v)
            nxt[f[(i + 1) % 3]] = f[(i + 2) % 3]
    start = next(iter(nxt))
    ring, cur = [start], nxt[start]
    while cur != start and len(ring) <= len(nxt):
        ring.append(cur)
        cur = nxt[cur]
    return ring


def edge_numbers(faces):
    """Edge numbers of the curve format: in face order, first time a vertex pair is seen."""
    edges = {}
    for f in faces:
        for i in range(len(f)):
            a, b = f[i], f[(i + 1) % len(f)]
            edges.setdefault(frozenset((a, b)), (len(edges), a))
    return edges


def write_hand_seeds(s, ctx):
    """Seeds gsd does not write: ascii / big-endian PLY clouds, ascii STL, queries, curves."""
    pts = read_xyz_cloud(s / "c.xyz")
    head = ["ply", "format ascii 1.0", "comment hand-written", f"element vertex {len(pts)}",
            *[f"property float {n}" for n in ("x", "y", "z", "nx", "ny", "nz")],
            "property uchar red", "end_header"]
    (s / "c_ascii.ply").write_text("\n".join(head + [" ".join(f"{x:.9g}" for x in p) + " 7"
                                                      for p in pts]) + "\n")
    head = ["ply", "format binary_big_endian 1.0", f"element vertex {len(pts)}",
            "property uchar red", "property double x", "property double y", "property double z",
            "property float nx", "property float ny", "property float nz", "end_header", ""]
    body = b"".join(struct.pack(">Bdddfff", 9, *p) for p in pts)
    (s / "c_be.ply").write_bytes("\n".join(head).encode() + body)

    verts, faces = read_obj_mesh(s / "m.obj")
    out = ["solid hand"]
    for f in faces:
        out += ["  facet normal 0 0 0", "    outer loop",
                *[f"      vertex {verts[i][0]:.9g} {verts[i][1]:.9g} {verts[i][2]:.9g}" for i in f],
                "    endloop", "  endfacet"]
    (s / "m_ascii.stl").write_text("\n".join(out + ["endsolid hand"]) + "\n")

    rng = random.Random(7)
    q = [rng.uniform(-0.8, 0.8) for _ in range(50 * 3)]
    (s / "q.npy").write_bytes(npy_build(1, 0, "{'descr': '<f4', 'fortran_order': False, "
                                        "'shape': (50, 3), }", struct.pack("<150f", *q)))

    # Curves around two far-apart vertices: 1-based v/e records + an open f-record piece...
    a = max(range(len(verts)), key=lambda i: verts[i][1])
    b = min(range(len(verts)), key=lambda i: verts[i][1])
    edges = edge_numbers(faces)
    ring = vertex_ring(faces, a)
    recs, poly = ["# hand-written curve: 1-based", "#l 3 4"], []
    for k, r in enumerate(ring):
        r2 = ring[(k + 1) % len(ring)]
        num, tail = edges[frozenset((r, r2))]
        recs += [f"v {r + 1}", f"e {num + 1} {0.25 if tail == r else 0.75}"]
        poly += [2 * k + 1, 2 * k + 2]
    tri = next(i for i, f in enumerate(faces) if b in f)
    recs += [f"l {' '.join(map(str, poly + [1]))}", "n",
             f"f {tri + 1} 0.2 0.2", f"f {tri + 1} 0.5 0.3", f"l {len(poly) + 1} {len(poly) + 2}"]
    (s / "ring.txt").write_text("\n".join(recs) + "\n")
    # Isolated points for `shm surface --points`: the same v/e/f records, no `l` or `n`.
    (s / "points.txt").write_text("\n".join(r for r in recs if r[:2] in ("v ", "e ", "f ", "# "))
                                  + "\n")
    # ... and the mesh .obj with `l` lines (one with negative indices) and a `p` line.
    ring_b = vertex_ring(faces, b)
    lines = (s / "m.obj").read_text().rstrip("\n").split("\n")
    lines += ["l " + " ".join(str(r + 1) for r in ring + ring[:1]),
              "l " + " ".join(str(r - len(verts)) for r in ring_b + ring_b[:1]),
              f"p {a + 1}"]
    (s / "loop.obj").write_text("\n".join(lines) + "\n")
    ctx["sizes"] = [len(verts), len(faces), len(edges), len(pts), len(ring)]


def make_seeds(gsd, s):
    ctx = {}
    for ext in ("ply", "xyz", "pc", "obj", "npy"):
        gsd_seed(gsd, s, "sample", "torus", "-n", "200", "-o", f"c.{ext}")
    for ext in ("obj", "off", "stl", "ply"):
        gsd_seed(gsd, s, "mesh", "sphere", "-r", "8", "-o", f"m.{ext}")
    write_hand_seeds(s, ctx)
    for m in ("m.obj", "m.off", "m.stl", "m_ascii.stl", "m.ply"):
        gsd_seed(gsd, s, "curve", m, "--plane", "0", "1", "0", "0", "-o", f"loop-{m}.txt")
    gsd_seed(gsd, s, "pat", "fit", "c.ply", "-o", "t.tori", "--device", "cpu")
    gsd_seed(gsd, s, "pat", "eval", "--tori", "t.tori", "--grid", "8", "--bounds", *BOUNDS,
             "-o", "g.npy", "--device", "cpu")
    shutil.copy(MODEL, s / "torusnet.safetensors")
    return ctx


# ----------------------------------------------------------------------------- formats
# A command is (argv template, expected outputs). In a template, {in} is the mutant, {S} the
# seed directory, {grid} the .npy beside a mutated sidecar, "DEV" stands for `--device cpu` (or
# nothing, for a share of the runs), "BOX" for `--bounds` and a box (mostly the unit box, else
# one of BOXES) and "BOX?" for the same or, half the time, nothing.
Command = namedtuple("Command", "argv outputs")
# companion: a seed file copied beside each mutant before its run: "sidecar" copies SEED.json
# to MUTANT.json (a grid with its bounds), "grid" copies the grid a mutated sidecar describes.
Format = namedtuple("Format", "name seed mutator commands companion", defaults=(None,))


def C(template, *outputs):
    # Every grid the CLI writes as .npy gets its sidecar, GRID.npy.json (docs/formats.md).
    if "--grid" in template.split():
        outputs += tuple(o + ".json" for o in outputs if o.endswith(".npy"))
    return Command(template.split(), outputs)


def cloud_cmds(render=True):
    cmds = [
        C("pat fit {in} -o out.tori DEV", "out.tori"),
        C("shm grid {in} --grid 8 BOX? -o out.npy DEV", "out.npy"),
        C("pat eval {in} --fitter jet --grid 8 BOX? -o out.npy DEV", "out.npy"),
        C("winding {in} --grid 8 BOX? -o out.npy DEV", "out.npy"),
        C("baseline sspd {in} --grid 8 BOX? -o out.npy DEV", "out.npy"),
        C("pat eval {in} --fitter jet --grid 8 -o out.vdb DEV", "out.vdb"),
    ]
    # (`gsd render X.npy` reads X.npy as a grid, never as a cloud)
    if render:
        cmds.append(C("render {in} --fitter jet --size 16 12 --supersample 1 --max-steps 64 BOX? "
                      "-o out.png DEV", "out.png"))
    return cmds


def mesh_cmds(seed):
    curve = "{S}/loop-%s.txt" % seed
    return [
        C("shm grid {in} --grid 8 BOX? -o out.npy DEV", "out.npy"),
        C("winding {in} --grid 8 BOX? -o out.npy DEV", "out.npy"),
        C("sdf {in} --grid 8 BOX? -o out.npy DEV", "out.npy"),
        C("sdf {in} --samples 64 --seed 1 -o out.npy DEV", "out.npy", "out.npy.json"),
        C("shm grid {in} --grid 8 BOX? -o out.vdb DEV", "out.vdb"),
        C("swn {in} --curves %s -o labels.npy" % curve, "labels.npy"),
        C("shm surface {in} --curves %s -o phi.npy" % curve, "phi.npy"),
        C("curve {in} --plane 0 1 0 0 -o loop.txt", "loop.txt"),
        C("mesh --from {in} --holes 1 --flip 0.2 --noise 0.01 --seed 3 -o out.obj", "out.obj"),
    ]


def mesh_format(name, seed, mutator):
    return Format(name, seed, mutator, mesh_cmds(seed))


CURVE_CMDS = [
    C("swn {S}/m.obj --curves {in} -o labels.npy", "labels.npy"),
    C("shm surface {S}/m.obj --curves {in} -o phi.npy", "phi.npy"),
    C("swn {S}/m.obj --curves {in} --method shm -o labels.npy", "labels.npy"),
]

GRID_CMDS = [
    C("slice {grid} BOX --at 0 --width 64 -o out.png", "out.png"),
    C("contour {grid} BOX? -o out.obj", "out.obj"),
    C("slice {grid} BOX? --axis x --at 0.3 --width 48 -o out.png", "out.png"),
    C("contour {grid} BOX --iso 0.05 -o out.ply", "out.ply"),
    C("render {grid} BOX? --size 16 12 --supersample 1 -o out.png DEV", "out.png"),
]

FORMATS = [
    Format("cloud-ply-bin", "c.ply", "ply-binary", cloud_cmds()),
    Format("cloud-ply-ascii", "c_ascii.ply", "ply-text", cloud_cmds()),
    Format("cloud-ply-be", "c_be.ply", "ply-binary", cloud_cmds()),
    Format("cloud-xyz", "c.xyz", "text", cloud_cmds()),
    Format("cloud-pc", "c.pc", "text", cloud_cmds()),
    Format("cloud-obj", "c.obj", "text", cloud_cmds()),
    Format("cloud-npy", "c.npy", "npy", cloud_cmds(render=False)),
    mesh_format("mesh-obj", "m.obj", "text"),
    mesh_format("mesh-off", "m.off", "off"),
    mesh_format("mesh-stl-bin", "m.stl", "stl"),
    mesh_format("mesh-stl-ascii", "m_ascii.stl", "text"),
    mesh_format("mesh-ply", "m.ply", "ply-binary"),
    Format("queries-npy", "q.npy", "npy", [
        C("pat eval --tori {S}/t.tori --queries {in} -o out.npy DEV", "out.npy"),
        C("winding {S}/m.obj --queries {in} -o out.npy DEV", "out.npy"),
        C("baseline shc {S}/c.ply --queries {in} -o out.npy DEV", "out.npy"),
        C("pat eval --tori {S}/t.tori --queries {in} -o out.npy --gradient grad.npy DEV",
          "out.npy", "grad.npy"),
    ]),
    # The mutated grid comes with the seed's sidecar (its bounds, unless BOX gives others).
    Format("grid-npy", "g.npy", "npy", GRID_CMDS + [
        C("render {S}/g.npy --color {in} --size 16 12 --supersample 1 -o out.png DEV", "out.png"),
    ], companion="sidecar"),
    # The sidecar mutated (text), beside the seed grid.
    Format("grid-sidecar", "g.npy.json", "text", GRID_CMDS + [
        C("render {S}/g.npy --color {grid} --size 16 12 --supersample 1 -o out.png DEV", "out.png"),
    ], companion="grid"),
    Format("tori", "t.tori", "tori", [
        C("pat eval --tori {in} --grid 8 BOX? -o out.npy DEV", "out.npy"),
        C("pat eval --tori {in} --queries {S}/q.npy -o out.npy DEV", "out.npy"),
        C("pat eval --tori {in} --grid 8 --exact -o out.npy DEV", "out.npy"),
        C("render --tori {in} --size 16 12 --supersample 1 --max-steps 64 BOX? -o out.png DEV",
          "out.png"),
    ]),
    Format("safetensors", "torusnet.safetensors", "safetensors", [
        C("pat fit {S}/c.ply --model {in} -o out.tori DEV", "out.tori"),
        C("pat eval {S}/c.ply --model {in} --grid 8 -o out.npy DEV", "out.npy"),
    ]),
    Format("curve-txt", "loop-m.obj.txt", "curve", CURVE_CMDS),
    Format("curve-txt-1based", "ring.txt", "curve", CURVE_CMDS),
    Format("points-txt", "points.txt", "curve", [
        C("shm surface {S}/m.obj --points {in} -o phi.npy", "phi.npy"),
        C("shm surface {S}/m.obj --points {in} --curves {S}/ring.txt -o phi.npy", "phi.npy"),
    ]),
    Format("curve-obj", "loop.obj", "curve", CURVE_CMDS + [
        C("swn {in} -o labels.npy", "labels.npy"),
        C("shm surface {in} -o phi.npy", "phi.npy"),
    ]),
]


def pick_box(rng):
    """The box for BOX / BOX? in this run: None (BOX? left out, BOX the unit box) half the time."""
    r = rng.random()
    return None if r < 0.5 else " ".join(BOUNDS) if r < 0.7 else rng.choice(BOXES)


def render(cmd, gsd, inp, seeds, device_cpu, box=None, grid=None, no_vdb=False):
    argv = [gsd]
    for tok in cmd.argv:
        if tok == "DEV":
            argv += ["--device", "cpu"] if device_cpu else []
        elif tok in ("BOX", "BOX?"):
            if box or tok == "BOX":
                argv += ["--bounds", *(box or " ".join(BOUNDS)).split()]
        elif no_vdb and tok.endswith(".vdb"):
            argv.append(tok[:-4] + ".npy")
        else:
            argv.append(tok.replace("{in}", str(inp)).replace("{S}", str(seeds))
                        .replace("{grid}", str(grid or inp)))
    return argv


def outputs_of(cmd, no_vdb=False):
    if not no_vdb:
        return cmd.outputs
    outs = []
    for o in cmd.outputs:
        outs += [o[:-4] + ".npy", o[:-4] + ".npy.json"] if o.endswith(".vdb") else [o]
    return tuple(outs)


def companion_files(fmt, mutant, seeds):
    """Copies the format's companion beside the mutant; returns (grid path, files made)."""
    if fmt.companion == "sidecar":
        side = Path(str(mutant) + ".json")
        shutil.copy(seeds / (fmt.seed + ".json"), side)
        return mutant, [side]
    if fmt.companion == "grid":
        grid = Path(str(mutant)[:-len(".json")])
        shutil.copy(seeds / fmt.seed[:-len(".json")], grid)
        return grid, [grid]
    return mutant, []


# ----------------------------------------------------------------------------- running

def child_env(memory_limit):
    env = dict(os.environ)
    env.update(ASAN_OPTIONS="detect_leaks=1:abort_on_error=1",
               UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1",
               OMP_NUM_THREADS="1", XDG_RUNTIME_DIR="/tmp")
    if memory_limit:
        env["GSD_MEMORY_LIMIT"] = memory_limit
    if os.environ.get("GSD_KEEP_LOADED"):
        env["LD_PRELOAD"] = os.environ["GSD_KEEP_LOADED"]
    return env


def rss_kib(pid):
    try:
        with open(f"/proc/{pid}/statm") as f:
            return int(f.read().split()[1]) * (os.sysconf("SC_PAGE_SIZE") // 1024)
    except (OSError, ValueError, IndexError):
        return 0


Outcome = namedtuple("Outcome", "rc timed_out rss_killed peak_kib output seconds cpu")
STOP = threading.Event()  # set on Ctrl-C: running children are killed, queued runs skipped


CLOCK_TICK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid):
    """User + system CPU time of a running process (all its threads), from /proc."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / CLOCK_TICK
    except (OSError, ValueError, IndexError):
        return 0.0


def execute(argv, cwd, env, timeout, max_rss_kib, cpu_timeout=0):
    """Runs argv in its own session; kills the group past `timeout` seconds of wall time, past
    `cpu_timeout` seconds of CPU time (when > 0: a limit that a loaded machine does not move),
    or with its RSS above the limit."""
    with tempfile.TemporaryFile() as out:
        t0 = time.monotonic()
        proc = subprocess.Popen(argv, cwd=cwd, env=env, stdin=subprocess.DEVNULL, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)
        timed_out = rss_killed = False
        delay, status, ru = 0.002, None, None
        while True:
            pid, status, ru = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            killed = None
            if STOP.is_set():
                killed = True
            elif time.monotonic() - t0 > timeout or (cpu_timeout > 0 and
                                                     cpu_seconds(proc.pid) > cpu_timeout):
                timed_out = killed = True
            elif rss_kib(proc.pid) > max_rss_kib:
                rss_killed = killed = True
            if killed:
                try:
                    os.killpg(proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                _, status, ru = os.wait4(proc.pid, 0)
                break
            time.sleep(delay)
            delay = min(delay * 1.5, 0.05)
        rc = os.waitstatus_to_exitcode(status)
        proc.returncode = rc  # reaped here; keeps Popen from waiting again
        seconds = time.monotonic() - t0
        out.seek(0)
        text = out.read().decode("utf-8", "replace")
    return Outcome(rc, timed_out, rss_killed, ru.ru_maxrss, text, seconds, ru.ru_utime + ru.ru_stime)


def first_line(output, markers):
    for line in output.splitlines():
        if any(m in line for m in markers):
            return line.strip()
    return ""


def classify(o, run_dir, outputs, max_rss_kib):
    """Returns (kind, reasons): kind is 'ok', 'error' or 'finding'."""
    reasons = []
    left = sorted(p.name for p in run_dir.iterdir())
    if o.timed_out:
        reasons.append(f"hang: killed at the time limit after {o.seconds:.1f} s, {o.cpu:.1f} s of CPU "
                       "(process group killed)")
    if o.rss_killed or o.peak_kib > max_rss_kib:
        reasons.append(f"peak RSS {o.peak_kib // 1024} MiB above the limit")
    marker = first_line(o.output, SANITIZER_MARKERS)
    if marker:
        reasons.append("sanitizer/abort report")
    if not o.timed_out and not o.rss_killed:
        if o.rc < 0:
            reasons.append(f"killed by signal {signal.Signals(-o.rc).name}")
        elif o.rc not in DOCUMENTED_EXITS:
            reasons.append(f"exit status {o.rc} outside {sorted(DOCUMENTED_EXITS)}")
        elif o.rc == 2:
            reasons.append("usage exit 2 although the arguments are valid")
        elif o.rc == 1:
            if left:
                reasons.append(f"partial output: the failed run left {', '.join(left)}")
            if "gsd: error:" not in o.output:
                reasons.append("exit 1 without a gsd error message")
            if "out of memory" in o.output:
                reasons.append("out of memory on an input of at most 1 MiB")
        elif o.rc == 0:
            for name in outputs:
                p = run_dir / name
                if not p.exists() or p.stat().st_size == 0:
                    reasons.append(f"exit 0 but output {name} is missing or empty")
            stray = [n for n in left if n not in outputs]
            if stray:
                reasons.append(f"stray file(s) after success: {', '.join(stray)}")
    if reasons:
        return "finding", reasons
    return ("ok" if o.rc == 0 else "error"), []


Result = namedtuple("Result", "fmt index kind reasons rc peak_kib seconds mutant argv run_dir "
                               "line ops repro cpu")


def first_message(output):
    return (first_line(output, SANITIZER_MARKERS) or first_line(output, ["gsd: error"])
            or (output.strip().splitlines() or [""])[-1])[:300]


class Campaign:
    def __init__(self, args, work, seeds, ctx, no_vdb=False):
        self.a, self.work, self.seeds, self.ctx, self.no_vdb = args, work, seeds, ctx, no_vdb
        self.env = child_env(args.memory_limit)
        self.max_rss_kib = args.max_rss_mb * 1024
        self.seed_cache = {}
        self.lock = threading.Lock()

    def seed_bytes(self, fmt):
        with self.lock:
            if fmt.name not in self.seed_cache:
                self.seed_cache[fmt.name] = (self.seeds / fmt.seed).read_bytes()
            return self.seed_cache[fmt.name]

    def repro(self, fmt, index):
        """The command line that regenerates and reruns mutant `index` of `fmt`, keeping it."""
        argv = ["python3", os.path.relpath(__file__), "--gsd", self.a.gsd_given,
                "--seed", str(self.a.seed), "--formats", fmt.name, "--index", str(index),
                "--timeout", f"{self.a.timeout:g}", "--cpu-timeout", f"{self.a.cpu_timeout:g}",
                "--keep-findings", "/tmp/gsd-finding"]
        if self.a.default_device_share != DEFAULT_DEVICE_SHARE:
            argv += ["--default-device-share", f"{self.a.default_device_share:g}"]
        return shlex.join(argv)

    def run_one(self, fmt, index, deadline=None):
        if STOP.is_set() or (deadline and time.monotonic() > deadline):
            return None
        rng = random.Random(f"{self.a.seed}:{fmt.name}:{index}")
        seed = self.seed_bytes(fmt)
        ctx = dict(self.ctx, curve=fmt.mutator == "curve",
                   off_faces=fmt.mutator == "off", header_end=_header_end(seed))
        data, ops = mutate(seed, fmt.mutator, ctx, rng)
        ext = fmt.seed.split(".", 1)[1]
        mutant = self.work / "mutants" / f"{fmt.name}-{index:05d}.{ext}"
        mutant.write_bytes(data)
        grid, extras = companion_files(fmt, mutant, self.seeds)
        cmd = fmt.commands[index % len(fmt.commands)]
        device_cpu = rng.random() >= self.a.default_device_share
        box = pick_box(rng)
        argv = render(cmd, self.a.gsd, mutant, self.seeds, device_cpu, box, grid, self.no_vdb)
        run_dir = self.work / "runs" / f"{fmt.name}-{index:05d}"
        run_dir.mkdir(parents=True)
        o = execute(argv, run_dir, self.env, self.a.timeout, self.max_rss_kib, self.a.cpu_timeout)
        kind, reasons = classify(o, run_dir, outputs_of(cmd, self.no_vdb), self.max_rss_kib)
        if kind != "finding" and not self.a.keep_all:
            shutil.rmtree(run_dir, ignore_errors=True)
            for f in [mutant] + extras:
                f.unlink()
        return Result(fmt.name, index, kind, reasons, o.rc, o.peak_kib, o.seconds, mutant, argv,
                      run_dir, first_message(o.output), ops, self.repro(fmt, index), o.cpu)


def _header_end(seed):
    for marker in (b"end_header\n", b"}"):
        k = seed.find(marker)
        if 0 <= k < 4096:
            return k + len(marker)
    return 256


def vdb_missing(camp):
    """True when this gsd cannot write .vdb (no OpenVDB plugin beside it): the campaign then
    writes those commands' grids as .npy (same computation, same mutants and commands)."""
    run_dir = camp.work / "runs" / "vdb-probe"
    run_dir.mkdir(parents=True)
    o = execute([camp.a.gsd, "-q", "winding", str(camp.seeds / "m.obj"), "--grid", "4", "-o",
                 "probe.vdb", "--device", "cpu"], run_dir, camp.env, 120, camp.max_rss_kib)
    shutil.rmtree(run_dir, ignore_errors=True)
    return o.rc != 0 and "cannot write .vdb" in o.output


def check_clean_runs(camp, formats):
    """Every command must succeed on its unmutated seed, or the campaign measures nothing."""
    bad = []
    for fmt in formats:
        for i, cmd in enumerate(fmt.commands):
            run_dir = camp.work / "runs" / f"clean-{fmt.name}-{i}"
            run_dir.mkdir(parents=True)
            seed = camp.seeds / fmt.seed
            grid = seed.with_suffix("") if fmt.companion == "grid" else seed
            argv = render(cmd, camp.a.gsd, seed, camp.seeds, True, None, grid, camp.no_vdb)
            o = execute(argv, run_dir, camp.env, camp.a.timeout, camp.max_rss_kib,
                        camp.a.cpu_timeout)
            kind, reasons = classify(o, run_dir, outputs_of(cmd, camp.no_vdb), camp.max_rss_kib)
            if kind != "ok":
                bad.append(f"  [{fmt.name}] {shlex.join(argv)}\n    exit {o.rc}: "
                           f"{'; '.join(reasons) or o.output.strip()[-300:]}")
            shutil.rmtree(run_dir, ignore_errors=True)
    if bad:
        print("setup: commands fail on their unmutated seeds:\n" + "\n".join(bad))
        sys.exit(2)


# ----------------------------------------------------------------------------- regressions
# DIR/cases.txt: one case a line, `FILE gsd-arguments...` ({in}: DIR/FILE, {D}: DIR; `#`
# starts a comment line). Each runs in an empty directory under the campaign's time limit and
# memory cap, and is judged as a mutant is: exit 0 with every output (the files after -o /
# --output / --gradient, and a --grid .npy's sidecar), or exit 1 with a `gsd: error:` line and
# nothing left behind.

Regression = namedtuple("Regression", "name lineno input argv outputs")
OUTPUT_FLAGS = ("-o", "--output", "--gradient")


def load_regressions(d):
    d = Path(d).resolve()
    manifest = d / "cases.txt"
    if not manifest.is_file():
        sys.exit(f"setup: {manifest} not found")
    cases = []
    for n, raw in enumerate(manifest.read_text().splitlines(), 1):
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        toks = shlex.split(raw)
        inp = d / toks[0]
        if len(toks) < 2 or not inp.is_file():
            sys.exit(f"setup: {manifest}:{n}: needs an existing FILE and gsd arguments")
        args = [t.replace("{in}", str(inp)).replace("{D}", str(d)) for t in toks[1:]]
        outs = tuple(args[i + 1] for i, t in enumerate(args[:-1]) if t in OUTPUT_FLAGS)
        cases.append(Regression(toks[0], n, inp, args, C(" ".join(args), *outs).outputs))
    return cases


def run_regressions(camp_args, work, cases):
    env = child_env(camp_args.memory_limit)
    max_rss_kib = camp_args.max_rss_mb * 1024
    results = []
    print(f"regressions: {len(cases)} case(s)", flush=True)
    for c in cases:
        if STOP.is_set():
            break
        run_dir = work / "regressions" / f"{c.lineno:03d}"
        run_dir.mkdir(parents=True)
        argv = [camp_args.gsd] + c.argv
        o = execute(argv, run_dir, env, camp_args.timeout, max_rss_kib, camp_args.cpu_timeout)
        kind, reasons = classify(o, run_dir, c.outputs, max_rss_kib)
        line = first_message(o.output)
        print(f"  {kind:<7} exit {o.rc:3d} {o.seconds:6.2f} s (cpu {o.cpu:6.2f} s) {o.peak_kib / 1024:5.0f} MiB  "
              f"{c.name}: {shlex.join(c.argv).replace(str(c.input), '{in}')}"
              + (f"\n          {line}" if kind != "ok" else ""), flush=True)
        if kind != "finding":
            shutil.rmtree(run_dir, ignore_errors=True)
        repro = f"cd \"$(mktemp -d)\" && {shlex.join(argv)}"
        results.append(Result("regressions", c.lineno, kind, reasons, o.rc, o.peak_kib, o.seconds,
                              c.input, argv, run_dir, line, ["cases.txt:%d" % c.lineno], repro,
                              o.cpu))
    return results


# ----------------------------------------------------------------------------- report

def summary_line(name, rs):
    c = Counter(r.kind for r in rs)
    peak = max((r.peak_kib for r in rs), default=0) / 1024
    slowest = max((r.seconds for r in rs), default=0)
    cpu = sum(r.cpu for r in rs)
    return (f"{name:<18} runs {len(rs):5d}  clean-errors {c['error']:5d}  successes {c['ok']:5d}"
            f"  findings {c['finding']:4d}  peak-RSS-max {peak:6.1f} MiB  slowest {slowest:5.2f} s"
            f"  cpu {cpu:6.1f} s")


def keep_finding(r, keep, seeds):
    """Copies the mutant (and, once, the seeds) under --keep-findings; returns the repro argv."""
    if not (keep / "seeds").exists():
        shutil.copytree(seeds, keep / "seeds")
    dst = keep / r.mutant.name
    shutil.copy(r.mutant, dst)
    for extra in (Path(str(r.mutant) + ".json"), Path(str(r.mutant)[:-len(".json")])):
        if r.mutant.name.endswith(".json") != extra.name.endswith(".json") and extra.exists():
            shutil.copy(extra, keep / extra.name)  # a format's companion file
    argv = [a.replace(str(r.mutant.parent), str(keep)).replace(str(seeds), str(keep / "seeds"))
            for a in r.argv]
    script = keep / (r.mutant.stem + ".sh")
    script.write_text("#!/bin/sh\n# %s\ncd \"$(mktemp -d)\" && %s\n"
                      % ("; ".join(r.reasons), shlex.join(argv)))
    script.chmod(0o755)
    return dst, argv


# Subcommands that take --device (without it they run with --device auto).
DEVICE_COMMANDS = ("pat", "baseline", "shm grid", "winding", "render")


def label(r):
    return f"cases.txt:{r.index}" if r.fmt == "regressions" else f"{r.fmt} #{r.index}"


def command_name(argv):
    sub = " ".join(argv[1:3] if len(argv) > 2 and argv[1] in ("shm", "pat", "baseline") else argv[1:2])
    if not any(sub == c or sub.startswith(c + " ") for c in DEVICE_COMMANDS):
        return sub
    dev = next((argv[i + 1] for i, a in enumerate(argv[:-1]) if a == "--device"), "auto")
    return sub + ("" if dev == "cpu" else f" (--device {dev})")


def print_slowest(results):
    """The slowest run of each command (by CPU time): the time budget adversarial inputs need."""
    worst = {}
    for r in results:
        name = command_name(r.argv)
        if name not in worst or r.cpu > worst[name].cpu:
            worst[name] = r
    if not worst:
        return
    print("\nSlowest run per command (CPU time; wall time; the run):")
    for name, r in sorted(worst.items(), key=lambda kv: -kv[1].cpu):
        print(f"  {name:<28} {r.cpu:6.2f} s  {r.seconds:6.2f} s  {label(r)} ({r.kind})")


def report(results, formats, args, seeds):
    print()
    if any(r.fmt == "regressions" for r in results):
        print(summary_line("regressions", [r for r in results if r.fmt == "regressions"]))
    for f in formats:
        rs = [r for r in results if r.fmt == f.name]
        if rs:
            print(summary_line(f.name, rs))
    print(summary_line("TOTAL", results))
    print_slowest(results)
    if MUTATOR_ERRORS:
        print("\nnote: mutation operators that raised (skipped; a bug in this tool, not in gsd):")
        for what, n in MUTATOR_ERRORS.most_common():
            print(f"  {n:4d} x  {what}")
    findings = [r for r in results if r.kind == "finding"]
    if not findings:
        return
    print(f"\n{len(findings)} finding(s):")
    keep = Path(args.keep_findings).resolve() if args.keep_findings else None
    if keep:
        keep.mkdir(parents=True, exist_ok=True)
    signatures = Counter()
    for r in findings:
        mutant, argv = keep_finding(r, keep, seeds) if keep and r.fmt != "regressions" \
            else (r.mutant, r.argv)
        print(f"- [{label(r)}] exit {r.rc} after {r.seconds:.1f} s: {'; '.join(r.reasons)}")
        print(f"    input:     {mutant}  (mutations: {', '.join(r.ops)})")
        print(f"    command:   {shlex.join(argv)}   (run in an empty directory; this run's: {r.run_dir})")
        print(f"    line:      {r.line}")
        print(f"    reproduce: {r.repro}")
        cmd_name = " ".join(a for a in r.argv[1:3] if not a.startswith(("/", "-")))
        key = re.sub(r"\d+", "N", r.reasons[0].split(": ")[0])
        signatures[(key, cmd_name, re.sub(r"\d+", "N", r.line)[:120])] += 1
    print("\nDistinct findings (first reason, command, first line with digits as N):")
    for (reason, cmd, line), n in signatures.most_common():
        print(f"  {n:4d} x  {reason} | gsd {cmd} | {line}")


DEFAULT_DEVICE_SHARE = 0.1


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--gsd", help="the gsd binary to test")
    p.add_argument("--count", type=int, default=200, help="mutants per format (200)")
    p.add_argument("--counts", default="",
                   help="per-format counts overriding --count: NAME=N,... (names or prefixes)")
    p.add_argument("--minutes", type=float, default=0,
                   help="run for this long instead: rounds of --block mutants per format")
    p.add_argument("--block", type=int, default=10, help="mutants per format and round (10)")
    p.add_argument("--index", type=int, help="run only mutant INDEX of each format (reproduce)")
    p.add_argument("--regressions", help="replay DIR/cases.txt before the mutants")
    p.add_argument("--timeout", type=float, default=20, help="wall-clock seconds per run (20)")
    p.add_argument("--cpu-timeout", type=float, default=0,
                   help="CPU seconds per run (0: none); with it, --timeout is a backstop for "
                        "runs that wait without computing")
    p.add_argument("--seed", type=int, default=1, help="campaign seed (1)")
    p.add_argument("--jobs", type=int, default=1, help="runs in parallel (1)")
    p.add_argument("--work", help="work directory, new or empty (default: a fresh temp dir)")
    p.add_argument("--formats", help="comma-separated format names or prefixes (default: all)")
    p.add_argument("--keep-findings", help="copy each finding's mutant + repro script here")
    p.add_argument("--max-rss-mb", type=int, default=2048, help="peak RSS limit per run (2048)")
    p.add_argument("--memory-limit", default="1G",
                   help="GSD_MEMORY_LIMIT for the children ('' to leave unset; 1G)")
    p.add_argument("--default-device-share", type=float, default=DEFAULT_DEVICE_SHARE,
                   help="fraction of runs without --device cpu (--device auto) (0.1)")
    p.add_argument("-v", "--verbose", action="store_true", help="print every run's outcome")
    p.add_argument("--list-formats", action="store_true", help="list the formats and exit")
    a = p.parse_args()
    if a.list_formats:
        for f in FORMATS:
            print(f"{f.name:<18} seed {f.seed:<22} mutator {f.mutator:<12} "
                  f"{len(f.commands)} commands: " + " | ".join(" ".join(c.argv[:2]) for c in f.commands))
        sys.exit(0)
    if not a.gsd:
        p.error("--gsd is required")
    a.gsd_given = a.gsd
    a.gsd = str(Path(a.gsd).resolve())
    if not os.access(a.gsd, os.X_OK):
        p.error(f"{a.gsd} is not an executable")
    a.keep_all = a.index is not None  # a reproduction keeps its mutant and run directory
    return a


def select_formats(spec):
    if not spec:
        return FORMATS
    chosen = []
    for want in (w.strip() for w in spec.split(",")):
        exact = [f for f in FORMATS if f.name == want]
        hits = exact or [f for f in FORMATS if f.name.startswith(want)]
        if not hits:
            sys.exit(f"unknown format {want!r}; known: {', '.join(f.name for f in FORMATS)}")
        chosen += [f for f in hits if f not in chosen]
    return chosen


def format_counts(args, formats):
    counts = {f.name: args.count for f in formats}
    for item in filter(None, (x.strip() for x in args.counts.split(","))):
        name, _, n = item.partition("=")
        if not n.isdigit():
            sys.exit(f"--counts: {item!r} is not NAME=N")
        for f in select_formats(name):
            if f.name in counts:
                counts[f.name] = int(n)
    return counts


def run_campaign(camp, pool, formats, counts, args):
    results = []
    if args.index is not None or not args.minutes:
        for fmt in formats:
            indices = [args.index] if args.index is not None else range(counts[fmt.name])
            if not indices:
                continue
            t0 = time.monotonic()
            rs = [r for r in pool.map(lambda i, f=fmt: camp.run_one(f, i), indices) if r]
            if args.verbose:
                for r in rs:
                    print(f"  {r.fmt}#{r.index} {r.kind:<7} exit {r.rc:3d} {r.seconds:5.2f} s cpu {r.cpu:5.2f} s "
                          f"[{','.join(r.ops)}] {shlex.join(r.argv[1:])}: {r.line[:150]}")
            results += rs
            print(summary_line(fmt.name, rs) + f"  (total {time.monotonic() - t0:.0f} s)",
                  flush=True)
        return results
    # --minutes: rounds of --block mutants of every format until the time is up (a run under
    # way at the deadline finishes; the indices of one round follow the last round's).
    t0 = time.monotonic()
    deadline = t0 + 60 * args.minutes
    rnd = 0
    while time.monotonic() < deadline and not STOP.is_set():
        jobs = [(f, i) for f in formats for i in range(rnd * args.block, (rnd + 1) * args.block)]
        rs = [r for r in pool.map(lambda fi: camp.run_one(fi[0], fi[1], deadline), jobs) if r]
        results += rs
        rnd += 1
        n_find = sum(r.kind == "finding" for r in results)
        print(f"round {rnd}: indices < {rnd * args.block}, {len(results)} runs, {n_find} findings, "
              f"{time.monotonic() - t0:.0f} s", flush=True)
    return results


def main():
    args = parse_args()
    t_start = time.monotonic()
    formats = select_formats(args.formats)
    counts = format_counts(args, formats)
    sampling = args.index is not None or args.minutes > 0 or any(counts.values())
    own_work = not args.work
    work = Path(args.work or tempfile.mkdtemp(prefix="gsd-mutate-")).resolve()
    if work.exists() and any(work.iterdir()):
        sys.exit(f"--work {work} is not empty")
    seeds = work / "seeds"
    for d in (seeds, work / "mutants", work / "runs"):
        d.mkdir(parents=True, exist_ok=True)
    what = (f"mutant {args.index} of each format" if args.index is not None
            else f"{args.minutes:g} minutes" if args.minutes
            else ", ".join(f"{n}:{c}" for n, c in counts.items() if c) or "no mutants")
    limit = f"{args.cpu_timeout:g} s of CPU ({args.timeout:g} s wall)" if args.cpu_timeout \
        else f"{args.timeout:g} s"
    print(f"gsd {args.gsd}\nwork {work}\nseed {args.seed}, {what}, "
          f"time limit {limit}, jobs {args.jobs}", flush=True)

    results = []
    if args.regressions:
        results += run_regressions(args, work, load_regressions(args.regressions))
    if sampling:
        ctx = make_seeds(args.gsd, seeds)
        camp = Campaign(args, work, seeds, ctx)
        camp.no_vdb = vdb_missing(camp)
        if camp.no_vdb:
            print("note: this gsd cannot write .vdb (no OpenVDB plugin): those commands write .npy")
        if args.index is None:
            check_clean_runs(camp, formats)
        with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            try:
                results += run_campaign(camp, pool, formats, counts, args)
            except KeyboardInterrupt:
                STOP.set()
                pool.shutdown(cancel_futures=True)
                sys.exit(f"interrupted; work directory: {work}")
    report(results, formats, args, seeds)
    print(f"\ncampaign took {time.monotonic() - t_start:.0f} s")
    has_findings = any(r.kind == "finding" for r in results)
    if own_work and not has_findings and not args.keep_all:
        shutil.rmtree(work, ignore_errors=True)
    elif has_findings or args.keep_all:
        print(f"work directory kept: {work}")
    return 1 if has_findings else 0


if __name__ == "__main__":
    sys.exit(main())
