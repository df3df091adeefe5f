"""Checks of cycles.py's model on hand-written traces: `python3 bench-m4/test_cycles.py`."""

import os
import tempfile
import unittest

import cycles


def trace(blocks, executed):
    """A QEMU-style `-d in_asm,exec,nochain` log of `blocks` ({start: [(encoding, mnemonic, operands)]})."""
    lines = []
    for start, instructions in blocks.items():
        lines.append("IN: f")
        address = start
        for encoding, mnemonic, operands in instructions:
            lines.append(f"0x{address:08x}:  {encoding}  {mnemonic} {operands}")
            address += 2 * len(encoding.split())
        lines.append("")
    for start in executed:
        lines.append(f"Trace 0: 0x7f0000000000 [00800408/{start:08x}/00000110/ff020200] f")
    handle, path = tempfile.mkstemp()
    with os.fdopen(handle, "w") as log:
        log.write("\n".join(lines) + "\n")
    return path


class Model(unittest.TestCase):
    def test_instruction_classes(self):
        self.assertEqual(cycles.base_cycles("vmla.f32", "s0, s1, s2"), (3, "alu"))
        self.assertEqual(cycles.base_cycles("vdiv.f32", "s0, s1, s2"), (14, "alu"))
        self.assertEqual(cycles.base_cycles("push", "{r4, r5, r6, r7, lr}"), (6, "multi"))
        self.assertEqual(cycles.base_cycles("pop", "{r4-r7, pc}"), (6, "return"))
        self.assertEqual(cycles.base_cycles("ldr.w", "r0, [r1, #4]"), (2, "mem"))
        self.assertEqual(cycles.base_cycles("bne", "#0x10"), (1, "branch"))
        self.assertEqual(cycles.literal_address(0x102, "ldr", "r0, [pc, #0x8]"), 0x10C)

    def test_loop_in_cache_pays_flash_once(self):
        # A two-instruction loop run 10 times: the first entry misses the
        # instruction cache (5 wait states), the taken branch back costs the
        # pipeline refill every time but the flash only once.
        loop = {0x100: [("3001", "adds", "r0, #1"), ("e7fd", "b", "#0x100")]}
        path = trace(loop, [0x100] * 10)
        try:
            blocks, executed, _ = cycles.parse(path)
            instructions, total, _, stalls = cycles.simulate(blocks, executed)
        finally:
            os.remove(path)
        self.assertEqual(instructions, 20)
        self.assertEqual(stalls["branch target from flash"], 5)
        # adds 1 + b 1, refill 2 on the nine branches that were followed.
        self.assertEqual(total, 20 + 9 * 2 + 5)

    def test_consecutive_loads_pipeline(self):
        loads = {0x200: [("6808", "ldr", "r0, [r1]"), ("684a", "ldr", "r2, [r1, #4]"), ("4770", "bx", "lr")]}
        path = trace(loads, [0x200])
        try:
            blocks, executed, _ = cycles.parse(path)
            _, total, _, _ = cycles.simulate(blocks, executed)
        finally:
            os.remove(path)
        # 5 (first fetch) + ldr 2 + ldr 1 + bx 1 (nothing follows: no refill).
        self.assertEqual(total, 9)


if __name__ == "__main__":
    unittest.main()
