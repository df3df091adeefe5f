"""Instructions executed per function from a QEMU `-d in_asm,exec,nochain` log.

`in_asm` lists each translation block's instructions once; `exec` logs every
block executed with its start address and symbol. With chaining off every
execution is logged, so a function's count is the sum over its blocks of
executions x instructions.
"""

import collections
import re
import subprocess
import sys

BLOCK_START = re.compile(r"^0x([0-9a-f]{8}):")
EXECUTED = re.compile(r"\[[0-9a-f]+/([0-9a-f]+)/[0-9a-f]+/[0-9a-f]+\] (.*)$")


def demangle(names):
    try:
        out = subprocess.run(
            ["rustfilt"], input="\n".join(names), capture_output=True, text=True, check=True
        ).stdout.splitlines()
        if len(out) == len(names):
            return out
    except (OSError, subprocess.CalledProcessError):
        pass
    return names


def main(path, top):
    block_size = {}
    executions = collections.Counter()
    start = None
    with open(path, errors="replace") as log:
        for line in log:
            if line.startswith("IN:"):
                start = None
                continue
            match = BLOCK_START.match(line)
            if match:
                address = int(match.group(1), 16)
                if start is None:
                    start = address
                    block_size[start] = 0
                block_size[start] += 1
                continue
            if line.startswith("Trace"):
                match = EXECUTED.search(line)
                if match:
                    executions[(int(match.group(1), 16), match.group(2))] += 1
    per_function = collections.Counter()
    for (address, name), count in executions.items():
        per_function[name] += count * block_size.get(address, 0)
    total = sum(per_function.values())
    rows = per_function.most_common(top)
    names = demangle([name for name, _ in rows])
    print(f"{total} instructions traced")
    for (_, count), name in zip(rows, names):
        print(f"{count:>11} {100.0 * count / max(total, 1):5.1f} %  {name[:120]}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 40)
