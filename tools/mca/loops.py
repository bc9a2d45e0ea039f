#!/usr/bin/env python3
"""Static throughput of the filters' hot loops, for hosts too noisy to time them.

    tools/mca/loops.py BINARY [EXPONENTIALS] [CPU]

Disassembles BINARY (a release build of the filter benchmark, `cargo bench -p
pathlight-denoise --bench filter --no-run`, or `pathlight` itself), finds every loop (a
backward jump) whose body holds EXPONENTIALS `vrndscaleps` (default 2: one exponential per
signal, as in SVGF's a-trous tap loop and the data-driven window with two signals) and runs
`llvm-mca -mcpu=CPU` (default icelake-server) on its body, as if it ran back to back. Prints,
per loop, its instructions, its stack references (spills) and llvm-mca's cycles per iteration
and block throughput. Needs `objdump` and `llvm-mca` (Debian: `binutils`, `llvm`).

A model, not a measurement: it knows neither the caches nor the real processor's window, so
use it to compare two builds of one loop, and time the result where the host allows.
"""
import re
import subprocess
import sys


def instructions(binary):
    listing = subprocess.run(
        ["objdump", "-d", "--no-show-raw-insn", binary],
        capture_output=True, text=True, check=True,
    ).stdout
    out = []
    for line in listing.split("\n"):
        m = re.match(r"\s*([0-9a-f]+):\s*(.*)", line)
        if m:
            out.append((int(m.group(1), 16), m.group(2)))
    return out


def main():
    binary = sys.argv[1]
    want = int(sys.argv[2]) if len(sys.argv) > 2 else 2
    cpu = sys.argv[3] if len(sys.argv) > 3 else "icelake-server"
    ins = instructions(binary)
    index = {a: i for i, (a, _) in enumerate(ins)}
    for i, (address, text) in enumerate(ins):
        m = re.match(r"j\w+\s+([0-9a-f]+)", text)
        if not m:
            continue
        target = int(m.group(1), 16)
        if target >= address or target not in index or i - index[target] > 1500:
            continue
        body = ins[index[target]:i + 1]
        if sum("vrndscale" in t for _, t in body) != want:
            continue
        lines = []
        for _, t in body:
            t = re.sub(r"\s*#.*", "", t)
            t = re.sub(r"<[^>]*>", "", t)
            if t.startswith(("j", "data16", "nop", "cs nop")):
                continue
            # Constants in the binary: any memory operand will do for the model.
            lines.append(re.sub(r"-?0x[0-9a-f]+\(%rip\)", "0x10(%rsp)", t))
        report = subprocess.run(
            ["llvm-mca", f"-mcpu={cpu}", "-iterations=300"],
            input="\n".join(lines) + "\n", capture_output=True, text=True, check=True,
        ).stdout
        cycles = int(re.search(r"Total Cycles:\s+(\d+)", report).group(1)) / 300
        block = re.search(r"Block RThroughput:\s+([\d.]+)", report).group(1)
        spills = sum("(%rsp)" in t for t in lines)
        divisions = sum(t.startswith("vdiv") for t in lines)
        print(f"loop {target:x}-{address:x}: {len(lines)} instructions, {spills} stack "
              f"references, {divisions} divisions, {cycles:.1f} cycles per iteration, "
              f"block throughput {block}")


if __name__ == "__main__":
    main()
