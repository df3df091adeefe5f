"""Cycle estimate for the STM32F407 at 168 MHz from a QEMU execution trace.

Reads the `-d in_asm,exec,nochain` log that `profile.sh` writes (every
translation block's instructions once, then every block executed) and applies
a stated per-instruction cycle model of the Cortex-M4F core plus a model of
the STM32F4 flash interface (5 wait states at 168 MHz, 2.7-3.6 V) behind its
ART accelerator (prefetch on, 64-line instruction cache, 8-line data cache,
128-bit lines). QEMU counts instructions, not cycles; this turns its trace into
the cycles the real part would spend, within the model's stated limits.

Core (Cortex-M4 TRM r0p1, tables 3-1 and 7-1): data processing, MUL, shifts,
compares, IT 1; MLA/MLS 2; long multiplies 1; SDIV/UDIV 12 (their worst);
single loads and stores 2, 1 when one follows another (pipelined);
LDRD/STRD 3; LDM/STM/PUSH/POP 1+N; a taken branch 1+P with P = 2 (pipeline
refill), a branch not taken 1; TBB/TBH 2+P; POP with PC 1+N+P. FPU: VADD,
VSUB, VMUL, VNMUL, VABS, VNEG, VCMP, VCVT, VMOV, VMRS 1; VMLA/VMLS/VFMA and
their negated forms 3; VDIV and VSQRT 14; VLDR/VSTR 2, VLDM/VSTM/VPUSH/VPOP
1+N (doubles count two words). Double-precision instructions do not exist on
the M4F: the compiler calls software routines, which the trace counts as the
integer code they are.

Flash (RM0090 section 3.5): a taken branch to a 16-byte line not in the
instruction cache stalls 5 cycles and brings the line in (LRU); running
sequentially into a line not in the cache stalls for what is left of the
6-cycle fetch the prefetch buffer started when the previous line began
(prefetched lines are not cached). A literal-pool load (PC-relative) that
misses the data cache stalls 5 cycles. Other data is taken to live in SRAM
(no wait state), which holds for the firmware: its statics and stack are in
SRAM; flash constants reached through a register are not modelled.

Not modelled: bus contention with DMA (the firmware uses none in the control
path), interrupt entry and exit (12 cycles each, outside the period), the
FPU's lazy stacking, and branch-target alignment (P taken as 2 always).

Usage: python3 cycles.py TRACE [FUNCTION [BUDGET_CYCLES]]
FUNCTION (a substring of a symbol) marks where each period begins: the
report then gives the instructions and cycles of every period that ends
inside the trace, besides the totals. With BUDGET_CYCLES the exit status is
1 when the worst period (ART on) needs more cycles than that.
"""

import collections
import re
import sys

WAIT_STATES = 5
FLASH_ACCESS = WAIT_STATES + 1
LINE_BYTES = 16
ICACHE_LINES = 64
DCACHE_LINES = 8
PIPELINE_REFILL = 2
CLOCK_HZ = 168_000_000
FLASH_END = 0x0010_0000

INSTRUCTION = re.compile(r"^0x([0-9a-f]{8}):\s+((?:[0-9a-f]{4} ?)+)\s+(\S+)\s*(.*)$")
EXECUTED = re.compile(r"\[[0-9a-f]+/([0-9a-f]+)/[0-9a-f]+/[0-9a-f]+\] (.*)$")
REGISTER_LIST = re.compile(r"\{([^}]*)\}")


class Instruction:
    __slots__ = ("address", "size", "mnemonic", "operands", "cycles", "kind", "literal")

    def __init__(self, address, encoding, mnemonic, operands):
        self.address = address
        self.size = 2 * len(encoding.split())
        self.mnemonic = mnemonic
        self.operands = operands
        self.cycles, self.kind = base_cycles(mnemonic, operands)
        self.literal = literal_address(address, mnemonic, operands)


def register_count(operands):
    match = REGISTER_LIST.search(operands)
    if not match:
        return 1
    count = 0
    for item in match.group(1).split(","):
        item = item.strip()
        if "-" in item:
            low, high = item.split("-")
            count += int(high.strip()[1:]) - int(low.strip()[1:]) + 1
        elif item:
            count += 1
    return count


def base_cycles(mnemonic, operands):
    """(cycles when not taken / not pipelined, kind) of one instruction."""
    m = mnemonic.split(".")[0]
    if m.startswith("v"):
        if m in ("vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms"):
            return 3, "alu"
        if m in ("vdiv", "vsqrt"):
            return 14, "alu"
        if m in ("vldr", "vstr"):
            return 2, "mem"
        if m in ("vldm", "vstm", "vldmia", "vstmia", "vldmdb", "vstmdb", "vpush", "vpop"):
            words = register_count(operands) * (2 if "d" in operands.split("{")[-1][:2] else 1)
            return 1 + words, "multi"
        return 1, "alu"
    if m in ("ldm", "ldmia", "ldmdb", "stm", "stmia", "stmdb", "push", "pop"):
        count = register_count(operands)
        if m == "pop" and "pc" in operands:
            return 1 + count, "return"
        if m.startswith("ldm") and "pc" in operands:
            return 1 + count, "return"
        return 1 + count, "multi"
    if m in ("ldrd", "strd"):
        return 3, "multi"
    if m.startswith("ldr") or m.startswith("str") or m in ("ldrex", "strex"):
        if m.startswith("ldr") and operands.split(",")[0].strip() == "pc":
            return 2, "return"
        return 2, "mem"
    if m in ("sdiv", "udiv"):
        return 12, "alu"
    if m in ("mla", "mls"):
        return 2, "alu"
    if m in ("tbb", "tbh"):
        return 2, "branch"
    if m in ("bl", "blx"):
        return 1, "call"
    if m in ("bx",):
        return 1, "return"
    if m in ("b", "cbz", "cbnz") or (m.startswith("b") and len(m) == 3 and m[1:] in CONDITIONS):
        return 1, "branch"
    if m.startswith("mov") and operands.split(",")[0].strip() == "pc":
        return 1, "return"
    return 1, "alu"


CONDITIONS = {"eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le", "al"}

LITERAL = re.compile(r"\[pc(?:,\s*#(-?0x[0-9a-f]+|-?\d+))?\]")


def literal_address(address, mnemonic, operands):
    m = mnemonic.split(".")[0]
    if not (m.startswith("ldr") or m == "vldr"):
        return None
    match = LITERAL.search(operands)
    if not match:
        return None
    offset = int(match.group(1), 0) if match.group(1) else 0
    return ((address + 4) & ~3) + offset


class Lru:
    def __init__(self, size):
        self.size = size
        self.lines = collections.OrderedDict()

    def hit(self, line):
        if line in self.lines:
            self.lines.move_to_end(line)
            return True
        return False

    def insert(self, line):
        self.lines[line] = True
        self.lines.move_to_end(line)
        if len(self.lines) > self.size:
            self.lines.popitem(last=False)


def parse(path):
    blocks = {}
    executed = []
    names = {}
    current = None
    with open(path, errors="replace") as log:
        for line in log:
            if line.startswith("IN:"):
                current = []
                continue
            match = INSTRUCTION.match(line)
            if match and current is not None:
                address = int(match.group(1), 16)
                if not current:
                    blocks[address] = current
                current.append(Instruction(address, match.group(2), match.group(3), match.group(4)))
                continue
            if line.startswith("Trace"):
                current = None
                match = EXECUTED.search(line)
                if match:
                    start = int(match.group(1), 16)
                    executed.append(start)
                    names.setdefault(start, match.group(2).strip())
    return blocks, executed, names


def simulate(blocks, executed, period_start=None, art=True):
    """Instructions, cycles and per-period figures of the executed blocks.

    `art` False keeps the prefetch buffer but no caches: every branch to
    another line waits for the flash, as does every literal load."""
    icache = Lru(ICACHE_LINES)
    dcache = Lru(DCACHE_LINES)
    cycles = 0
    instructions = 0
    periods = []
    period_mark = None
    current_line = None
    line_entered_at = 0
    previous_kind = None
    fallthrough = None
    stalls = collections.Counter()
    for index, start in enumerate(executed):
        block = blocks.get(start)
        if not block:
            continue
        if period_start is not None and start == period_start:
            if period_mark is not None:
                periods.append((instructions - period_mark[0], cycles - period_mark[1]))
            period_mark = (instructions, cycles)
        following = executed[index + 1] if index + 1 < len(executed) else None
        sequential_entry = start == fallthrough
        for position, instruction in enumerate(block):
            line = instruction.address // LINE_BYTES
            if instruction.address < FLASH_END and line != current_line:
                jumped_here = position == 0 and not sequential_entry
                if art and icache.hit(line):
                    pass
                elif jumped_here:
                    cycles += WAIT_STATES
                    stalls["branch target from flash"] += WAIT_STATES
                    if art:
                        icache.insert(line)
                else:
                    wait = max(0, FLASH_ACCESS - (cycles - line_entered_at))
                    cycles += wait
                    stalls["sequential line not yet prefetched"] += wait
                current_line = line
                line_entered_at = cycles
            cost = instruction.cycles
            if instruction.kind == "mem" and previous_kind in ("mem", "multi"):
                cost -= 1
            if instruction.literal is not None and instruction.literal < FLASH_END:
                literal_line = instruction.literal // LINE_BYTES
                if not (art and dcache.hit(literal_line)):
                    cycles += WAIT_STATES
                    stalls["literal from flash"] += WAIT_STATES
                    if art:
                        dcache.insert(literal_line)
            if position == len(block) - 1 and instruction.kind in ("branch", "call", "return"):
                if following is not None and following != instruction.address + instruction.size:
                    cost += PIPELINE_REFILL
                    stalls["pipeline refill"] += PIPELINE_REFILL
            cycles += cost
            instructions += 1
            previous_kind = instruction.kind
        fallthrough = block[-1].address + block[-1].size
    return instructions, cycles, periods, stalls


def summary(label, instructions, cycles, periods, stalls):
    print(f"{label}: {instructions} instructions, {cycles} cycles, {cycles / max(instructions, 1):.3f} cycles per instruction")
    for cause, count in stalls.most_common():
        print(f"  {cause}: {count} cycles ({100.0 * count / max(cycles, 1):.1f} %)")
    if periods:
        counts = sorted(c for _, c in periods)
        inst = sorted(i for i, _ in periods)
        mean_c = sum(counts) / len(counts)
        mean_i = sum(inst) / len(inst)
        print(
            f"  {len(periods)} periods: instructions mean {mean_i:.0f} worst {inst[-1]}; "
            f"cycles mean {mean_c:.0f} worst {counts[-1]} "
            f"({1e6 * mean_c / CLOCK_HZ:.1f} us mean, {1e6 * counts[-1] / CLOCK_HZ:.1f} us worst at 168 MHz)"
        )


def main(path, function=None, budget=None):
    blocks, executed, names = parse(path)
    period_start = None
    if function:
        candidates = [start for start, name in names.items() if function in name]
        if not candidates:
            sys.exit(f"cycles.py: no executed block belongs to a symbol containing {function!r}")
        period_start = min(candidates)
        print(f"periods start at 0x{period_start:08x} ({names[period_start][:100]})")
    with_art = simulate(blocks, executed, period_start, art=True)
    summary("ART on (prefetch, I and D caches)", *with_art)
    summary("caches off (prefetch only)", *simulate(blocks, executed, period_start, art=False))
    periods = with_art[2]
    if budget is not None and periods:
        worst = max(c for _, c in periods)
        verdict = "within" if worst <= budget else "OVER"
        print(f"worst period {worst} cycles: {verdict} the budget of {budget} cycles")
        if worst > budget:
            sys.exit(1)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(
        sys.argv[1],
        sys.argv[2] if len(sys.argv) > 2 else None,
        int(sys.argv[3]) if len(sys.argv) > 3 else None,
    )
