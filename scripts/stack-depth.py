#!/usr/bin/env python3
"""Deepest call chains of a firmware image, from its disassembly.

    llvm-objdump -d --no-show-raw-insn -C target/firmware/qemu.elf > /tmp/fw.dis
    scripts/stack-depth.py /tmp/fw.dis 'poll::h'          # every task poll's deepest chain
    scripts/stack-depth.py /tmp/fw.dis 'NONE' 'poll_work'  # a function's callees, deepest first

A function's frame is what its prologue reserves (push, vpush, sub sp); a chain
follows direct calls and tail calls (bl, b.w). It is an estimate: indirect
calls (the executors polling their tasks, interrupt entry with its 104-byte
FPU frame) are not followed, and recursion is cut. The painted high-water mark
the firmware reports (`RuntimeReport.stack_used_bytes`) is the measurement;
this says which frames make it up.
"""
import re
import sys


def parse(path):
    current, calls, frame = None, {}, {}
    for line in open(path):
        m = re.match(r'^[0-9a-f]+ <(.*)>:', line)
        if m:
            if m.group(1).startswith('$'):
                continue
            current = m.group(1)
            calls.setdefault(current, set())
            frame.setdefault(current, 0)
            continue
        if current is None:
            continue
        m = re.search(r'\bsub(?:\.w)?\s+sp, (?:sp, )?#(0x[0-9a-f]+|\d+)', line)
        if m:
            frame[current] += int(m.group(1), 0)
        m = re.search(r'\bpush(?:\.w)?\s+\{([^}]*)\}', line)
        if m:
            frame[current] += 4 * len(m.group(1).split(','))
        m = re.search(r'\bvpush\s+\{([^}]*)\}', line)
        if m:
            frame[current] += 8 * len(m.group(1).split(','))
        m = re.search(r'\b(bl|blx|b\.w|b)\s+0x[0-9a-f]+ <([^>+]*)', line)
        if m and m.group(2) != current and not m.group(2).startswith('$'):
            calls[current].add(m.group(2))
    return calls, frame


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    calls, frame = parse(sys.argv[1])
    memo = {}

    def depth(function, path=()):
        if function in memo:
            return memo[function]
        if function in path:
            return 0, [function + ' (recursion, cut)']
        best = (0, [])
        for callee in calls.get(function, ()):
            candidate = depth(callee, path + (function,))
            if candidate[0] > best[0]:
                best = candidate
        result = (frame.get(function, 0) + best[0], [function] + best[1])
        memo[function] = result
        return result

    for function in calls:
        if sys.argv[2] in function:
            total, chain = depth(function)
            print(total, function)
            for link in chain:
                print('   ', frame.get(link, 0), link[:120])
    if len(sys.argv) > 3:
        for function in calls:
            if sys.argv[3] in function:
                print('callees of', function[:100], 'own frame', frame.get(function))
                ranked = sorted(calls[function], key=lambda c: -depth(c)[0])
                for callee in ranked[:15]:
                    print('   ', depth(callee)[0], callee[:120])


if __name__ == '__main__':
    main()
