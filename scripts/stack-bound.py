#!/usr/bin/env python3
"""Worst-case stack bound of a Cortex-M image from its call graph.

    scripts/stack-bound.py IMAGE.elf [--executor NAME=PATTERN ...] [--others NAME]
                           [--limit BYTES] [--show N]

Reads the image's disassembly (llvm-objdump from rustup's llvm-tools) and
builds its call graph: direct calls (`bl`), tail calls (a branch into another
function) and indirect calls (`blx rN`, `bx rN`), each of which may reach any
function whose address the image stores or builds (vtables, task pointers:
a 32-bit word in a literal pool, .rodata or .data, or a MOVW/MOVT pair,
equal to the function's address with the Thumb bit).
A function's frame is everything its code takes off the stack (every `push`,
`vpush`, `sub sp`, pre-indexed store to sp and `stmdb sp!`, summed, so a
frame split between branches is counted whole: an over-estimate). Its depth
is its frame plus the deepest callee's depth.

The bound is the deepest path from the reset handler (thread mode) plus, for
every exception and interrupt handler in the vector table, its own deepest
path and the 104-byte exception frame the hardware stacks with the FPU's
context: every handler is assumed able to preempt every other once, which
over-counts handlers that share a priority.

It refuses to give a number where there is none: a cycle of direct calls
(recursion) or a stack adjustment by a register (a variable-sized frame)
is reported with the functions involved, and the exit status is 2. Two
kinds of cycle are cut, counted and listed instead: a cycle that passes
through an indirect call (the address-taken set joins every vtable, so
`core::fmt`'s writers seem to call each other round in circles that no real
call makes), and a panic raised inside the panic handler, which recurses
until the MPU's stack guard stops it in the fail-safe MemManage handler.

Only an executor calls a task's poll function through its pointer: with
--executor the bound charges each task to the executor that runs it (the
thread executor's tasks to the reset path, an interrupt executor's tasks to
its handler) instead of to every executor.
With --limit the exit status is 1 when the bound exceeds the limit.
"""

import argparse
import collections
import glob
import os
import re
import subprocess
import sys

EXCEPTION_FRAME_BYTES = 104  # 8 core words + 18 FPU words (S0-S15, FPSCR, reserved)

FUNCTION = re.compile(r"^([0-9a-f]{8}) <(.+)>:$")
ADDRESS = re.compile(r"^\s*([0-9a-f]+):")
TARGET = re.compile(r"0x([0-9a-f]+) <([^>+]+)(\+0x[0-9a-f]+)?>")
REGISTERS = re.compile(r"\{([^}]*)\}")
NEGATIVE_OFFSET = re.compile(r"\[sp, #-(0x[0-9a-f]+|\d+)\]!")


def tool(name):
    found = glob.glob(os.path.join(sysroot(), "lib/rustlib/*/bin", name))
    if found:
        return found[0]
    sys.exit(f"stack-bound: {name} not found (rustup component add llvm-tools)")


def sysroot():
    return subprocess.run(["rustc", "--print", "sysroot"], capture_output=True, text=True, check=True).stdout.strip()


def register_words(operands):
    match = REGISTERS.search(operands)
    if not match:
        return 0
    words = 0
    for item in match.group(1).split(","):
        item = item.strip()
        if not item:
            continue
        if "-" in item:
            low, high = (part.strip() for part in item.split("-"))
            count = int(high[1:]) - int(low[1:]) + 1
            words += count * (2 if low.startswith("d") else 1)
        else:
            words += 2 if item.startswith("d") else 1
    return words


def stack_taken(mnemonic, operands):
    """Bytes this instruction takes off the stack, or None for a variable amount."""
    m = mnemonic.split(".")[0]
    if m in ("push", "vpush"):
        return 4 * register_words(operands)
    if m in ("stmdb", "vstmdb") and operands.startswith("sp!"):
        return 4 * register_words(operands)
    if m in ("sub", "subw", "subs") and operands.replace(" ", "").startswith("sp,"):
        parts = [p.strip() for p in operands.split(",")]
        last = parts[-1]
        if last.startswith("#"):
            return int(last[1:], 0)
        return None
    if m.startswith("str") and "[sp, #-" in operands and operands.endswith("]!"):
        return int(NEGATIVE_OFFSET.search(operands).group(1), 0)
    if m == "mov" and operands.replace(" ", "").startswith("sp,"):
        return None
    return 0


class Function:
    def __init__(self, start, name):
        self.start = start
        self.end = start
        self.name = name
        self.frame = 0
        self.variable_frame = False
        self.calls = set()
        self.indirect = False


def parse(image):
    listing = subprocess.run(
        [tool("llvm-objdump"), "-d", "--no-show-raw-insn", image], capture_output=True, text=True, check=True
    ).stdout
    functions = {}
    current = None
    low_halves = {}
    words = []
    for line in listing.splitlines():
        header = FUNCTION.match(line)
        if header:
            current = Function(int(header.group(1), 16), header.group(2))
            low_halves = {}
            functions[current.start] = current
            continue
        fields = line.split("\t")
        address_field = ADDRESS.match(fields[0])
        if not (address_field and current and len(fields) >= 2):
            continue
        address = int(address_field.group(1), 16)
        mnemonic = fields[1].strip()
        text = fields[2] if len(fields) > 2 else ""
        if mnemonic == ".word":
            words.append(int(text.strip(), 16))
            continue
        operands = text.split("@")[0].strip()
        if mnemonic.startswith("movw") or mnemonic.startswith("movt"):
            register, _, value = operands.partition(",")
            value = int(value.strip().lstrip("#"), 0)
            if mnemonic.startswith("movw"):
                low_halves[register] = value
            elif register in low_halves:
                words.append((value << 16) | low_halves.pop(register))
        current.end = max(current.end, address + 2)
        taken = stack_taken(mnemonic, operands)
        if taken is None:
            current.variable_frame = True
        else:
            current.frame += taken
        m = mnemonic.split(".")[0]
        target = TARGET.search(text.split("@")[0])
        if m in ("bl", "blx") and target:
            current.calls.add(int(target.group(1), 16))
        elif m in ("blx", "bx") and operands.strip() not in ("lr",):
            current.indirect = True
        elif m.startswith("b") and target and not m.startswith("bic") and not m.startswith("bfc"):
            destination = int(target.group(1), 16)
            if target.group(3) is None and destination != current.start:
                current.calls.add(destination)  # a tail call to another function's start
    # Data words: vtables and task pointers live in .rodata / .data.
    words += section_words(image, ".rodata", ".data")
    taken = {w & ~1 for w in words if w & 1 and (w & ~1) in functions}
    return functions, taken


def section_words(image, *sections):
    """The little-endian 32-bit words of `sections`, from a hex dump."""
    arguments = [tool("llvm-objdump"), "-s"]
    for section in sections:
        arguments += ["-j", section]
    dump = subprocess.run(arguments + [image], capture_output=True, text=True).stdout
    words = []
    for line in dump.splitlines():
        fields = line.split()
        if len(fields) < 2 or not re.fullmatch(r"[0-9a-f]+", fields[0]):
            continue
        for chunk in fields[1:5]:
            if re.fullmatch(r"[0-9a-f]{8}", chunk):
                words.append(int.from_bytes(bytes.fromhex(chunk), "little"))
    return words


def vector_table(image):
    entries = section_words(image, ".vector_table")
    # Entry 0 is the initial stack pointer, entry 1 the reset handler.
    return entries[1] & ~1 if len(entries) > 1 else None, {e & ~1 for e in entries[2:] if e & 1}


def is_task(function):
    return "TaskStorage" in function.name and "4poll" in function.name


def depths(functions, taken, tasks, executors=frozenset()):
    """Depth of every function when the executors poll `tasks`; cycles found."""
    all_tasks = {start for start in taken if is_task(functions[start])}
    memo = {}
    path = []
    on_path = set()
    problems = []

    cut = collections.Counter()

    def callees(function):
        direct = [(c, False) for c in function.calls if c in functions]
        if function.indirect:
            # Only an executor calls a task's poll function through its
            # pointer: the embassy executors, the firmware's own thread
            # executor and the interrupt handlers that run one.
            targets = taken - all_tasks
            if "executor" in function.name or function.start in executors:
                targets = targets | tasks
            direct += [(c, True) for c in targets if c not in function.calls]
        return direct

    through = []  # whether each edge on the path is an indirect call

    def visit(start, indirect=False):
        function = functions[start]
        if start in on_path:
            index = path.index(start)
            names = [functions[s].name for s in path[index:]] + [function.name]
            if indirect or any(through[index + 1 :]):
                cut["a cycle through an indirect call"] += 1
            elif any("rust_begin_unwind" in n for n in names):
                cut["a panic while panicking (ends at the stack guard)"] += 1
            else:
                problems.append("recursion: " + " -> ".join(names))
            return 0
        if start in memo:
            return memo[start]
        if function.variable_frame:
            problems.append(f"variable-sized frame: {function.name}")
        on_path.add(start)
        path.append(start)
        through.append(indirect)
        deepest, via = 0, None
        for callee, through_pointer in callees(function):
            depth = visit(callee, through_pointer)
            if depth > deepest:
                deepest, via = depth, callee
        path.pop()
        through.pop()
        on_path.discard(start)
        memo[start] = function.frame + deepest
        function.via = via
        return memo[start]

    sys.setrecursionlimit(100_000)
    return visit, problems, cut


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("image")
    parser.add_argument("--limit", type=int)
    parser.add_argument("--show", type=int, default=12, help="frames of the deepest path to print")
    parser.add_argument(
        "--executor",
        action="append",
        default=[],
        type=lambda text: tuple(text.split("=", 1)),
        metavar="NAME=PATTERN",
        help="executor NAME (`thread`, or the handler that runs an interrupt executor) polls the tasks whose poll "
        "function calls a function whose name holds PATTERN; repeatable (default: every executor polls every task)",
    )
    parser.add_argument("--others", help="the executor that polls the tasks no --executor pattern matches")
    args = parser.parse_args()
    functions, taken = parse(args.image)
    reset, handlers = vector_table(args.image)
    if reset not in functions:
        sys.exit("stack-bound: no reset handler in the vector table")
    all_tasks = {start for start in taken if is_task(functions[start])}
    runs = {}  # executor name ("thread" or a handler) -> the tasks it polls
    for start in sorted(all_tasks):
        callee_names = [functions[c].name for c in functions[start].calls if c in functions]
        owner = next((name for name, pattern in args.executor if any(pattern in n for n in callee_names)), args.others)
        if owner is None and args.executor:
            sys.exit(f"stack-bound: no --executor pattern matches task {functions[start].name} and no --others")
        runs.setdefault(owner, set()).add(start)
    if not args.executor:
        runs = {None: all_tasks}

    def tasks_of(name):
        return runs.get(None, set()) | runs.get(name, set())

    problems, cut = [], collections.Counter()

    def depth_of(root, name, executors=frozenset()):
        visit, found, cuts = depths(functions, taken, tasks_of(name), executors)
        depth = visit(root)
        problems.extend(found)
        cut.update(cuts)
        return depth

    thread = depth_of(reset, "thread")
    thread_via = {start: getattr(f, "via", None) for start, f in functions.items()}
    handler_depths = []
    handler_via = {}
    for handler in sorted(handlers):
        if handler not in functions:
            continue
        name = functions[handler].name
        depth = depth_of(handler, name, {handler} if name in runs else frozenset())
        handler_depths.append((depth + EXCEPTION_FRAME_BYTES, name, handler))
        handler_via[handler] = {start: getattr(f, "via", None) for start, f in functions.items()}
    handler_depths.sort(reverse=True)
    if problems:
        for problem in sorted(set(problems))[:20]:
            print(f"stack-bound: {problem}", file=sys.stderr)
        sys.exit(2)
    bound = thread + sum(d for d, _, _ in handler_depths)
    print(f"{os.path.basename(args.image)}: {len(functions)} functions, {len(taken)} address-taken")
    for owner, started in sorted(runs.items(), key=lambda item: str(item[0])):
        print(f"  executor {owner or 'any'} polls {len(started)} task(s)")

    def show_path(start, via):
        shown = 0
        while start is not None and shown < args.show:
            print(f"    {functions[start].frame:>6}  {functions[start].name[:110]}")
            start, shown = via.get(start), shown + 1

    print(f"  thread mode from reset: {thread} bytes; deepest path:")
    show_path(reset, thread_via)
    for depth, name, _ in handler_depths[:8]:
        print(f"  handler {name[:60]}: {depth} bytes (with its exception frame)")
    if handler_depths:
        print("  deepest handler's path:")
        show_path(handler_depths[0][2], handler_via[handler_depths[0][2]])
    for reason, count in cut.items():
        print(f"  paths cut: {count} x {reason}")
    print(f"  bound: {bound} bytes (thread + every handler preempting once)")
    if args.limit is not None and bound > args.limit:
        print(f"stack-bound: {bound} bytes exceed the limit of {args.limit}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
