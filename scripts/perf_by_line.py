#!/usr/bin/env python3
"""A `perf record` profile of an izb binary by function and by source line,
with the inlined frames `perf report` folds into their caller.

    perf record -F 5000 -o perf.data target/release/izb render ...
    scripts/perf_by_line.py perf.data target/release/izb [--match REGEX] [--top N]

`--match` keeps the samples whose inline chain passes through a source file
matching REGEX (e.g. 'cpu/(bin|receivers|footprint)') and prints their share
of all samples. Each sample's address in the file is its address in memory
less the mapping's start, plus the mapping's file offset, plus the text
segment's virtual address less its file offset (0x1000 for this crate's
release builds): without that last term every line is another function's
(sessions 16-26 of paper-notes/performance.md read lines that way; their
function-level figures came from `perf report` and stand).
"""
import argparse
import collections
import re
import subprocess


def text_segment_delta(binary):
    """p_vaddr - p_offset of the executable LOAD segment."""
    out = subprocess.run(["readelf", "-lW", binary], capture_output=True, text=True).stdout
    for line in out.splitlines():
        f = line.split()
        if f and f[0] == "LOAD" and "E" in f[-2]:
            return int(f[2], 16) - int(f[1], 16)
    return 0


def sample_addresses(data, binary):
    """Samples per file address of `binary`, and the total sample count."""
    out = subprocess.run(
        ["perf", "script", "-i", data, "-F", "ip", "--show-mmap-events"],
        capture_output=True,
        text=True,
    ).stdout
    delta = text_segment_delta(binary)
    name = binary.split("/")[-1]
    maps, counts, total = [], collections.Counter(), 0
    for line in out.splitlines():
        if "PERF_RECORD_MMAP" in line:
            m = re.search(r"\[(0x[0-9a-f]+)\((0x[0-9a-f]+)\) @ (0x[0-9a-f]+)", line)
            if m and name in line:
                maps.append(tuple(int(g, 16) for g in m.groups()))
            continue
        try:
            ip = int(line.strip(), 16)
        except ValueError:
            continue
        total += 1
        for start, size, offset in maps:
            if start <= ip < start + size:
                counts[ip - start + offset + delta] += 1
                break
    return counts, total


def inline_chains(binary, addresses):
    """Per address, its inline chain innermost first, as (function,
    file:line, whether the frame is the crate's own rather than std's or a
    dependency's)."""
    out = subprocess.run(
        ["addr2line", "-e", binary, "-i", "-f", "-C", "-a"] + [hex(a) for a in addresses],
        capture_output=True,
        text=True,
    ).stdout
    chains = []
    for block in re.split(r"\n(?=0x[0-9a-f]+\n)", out.strip()):
        lines = block.split("\n")[1:]
        chain = []
        for func, place in zip(lines[0::2], lines[1::2]):
            place = place.split(" ")[0]
            own = "/rustc/" not in place and "/.cargo/" not in place
            chain.append((func, place.split("/src/", 1)[-1], own))
        chains.append(chain)
    return chains


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("data")
    p.add_argument("binary")
    p.add_argument("--match", help="keep samples whose inline chain passes a file matching this")
    p.add_argument("--top", type=int, default=30)
    a = p.parse_args()
    counts, total = sample_addresses(a.data, a.binary)
    top = counts.most_common(50_000)
    chains = inline_chains(a.binary, [addr for addr, _ in top])
    pattern = re.compile(a.match) if a.match else None
    functions, lines, kept = collections.Counter(), collections.Counter(), 0
    for chain, (_, n) in zip(chains, top):
        if pattern and not any(pattern.search(place) for _, place, _ in chain):
            continue
        kept += n
        own = [frame for frame in chain if frame[2]] or chain
        functions[own[0][0][:100]] += n
        lines[" <- ".join(place for _, place, _ in own[:3])] += n
    print(f"{total} samples, {kept} kept ({100 * kept / max(total, 1):.1f} %)")
    for title, table in (("functions (the innermost of the crate's own, inlined ones included)", functions), ("lines", lines)):
        print(f"--- {title}, share of the kept samples")
        for key, n in table.most_common(a.top):
            print(f"{100 * n / max(kept, 1):5.1f} %  {key}")


if __name__ == "__main__":
    main()
