//! The STM32 image drops the amplifier enable first: in `__pre_init` (the
//! first code after reset, before RAM is initialised and the stack painted)
//! and in the panic handler, HardFault and the default handler, before any
//! call. There is no STM32 to run, so the test reads the linked image that
//! `scripts/build-firmware` leaves (`target/firmware/stm32f407.elf`, or
//! `FIRMWARE_STM32_ELF`) and follows each function's Thumb code to its first
//! store: its base register must hold GPIOE_BSRR's address, loaded from the
//! literal pool or formed by MOVW/MOVT, with no branch-and-link before it. Without the image (the
//! firmware not built) the test says so and passes.
//!
//! MemManage (the stack guard's fault) is checked the same way. A second
//! test checks that the RTT log has no blocking writer. Both images are
//! checked: the board on its own ticker and the one built for lock step
//! with the simulated plant (`stm32f407-lock-step.elf`), which runs on real
//! hardware too.
//!
//! Only what the handlers need is decoded: 16-bit PC-relative LDR (the
//! literal loads), MOVW/MOVT, 16-bit STR and 32-bit STR.W (stores), BL
//! (calls), BX LR.

use std::path::PathBuf;

/// GPIOE_BSRR: a store of bit 31 (BR15) drops the enable, PE15.
const GPIOE_BSRR: u32 = 0x4002_1018;
/// GPIOE_MODER: PE15 made an output (after its latch is low).
const GPIOE_MODER: u32 = 0x4002_1000;

fn image_paths() -> Vec<PathBuf> {
    if let Some(path) = std::env::var_os("FIRMWARE_STM32_ELF") {
        return vec![PathBuf::from(path)];
    }
    let dir = integration_tests::qemu::target_dir().join("firmware");
    vec![
        dir.join("stm32f407.elf"),
        dir.join("stm32f407-lock-step.elf"),
    ]
}

/// The images built, each read whole; the ones not built are named.
fn images() -> Vec<(PathBuf, Image)> {
    let mut images = Vec::new();
    for path in image_paths() {
        match std::fs::read(&path) {
            Ok(bytes) => images.push((path, Image::parse(bytes))),
            Err(_) => eprintln!(
                "{}: not built (scripts/build-firmware); nothing to check",
                path.display()
            ),
        }
    }
    images
}

fn u16_at(bytes: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(bytes.get(at..at + 2)?.try_into().ok()?))
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
}

/// An ELF32 little-endian image: its loaded sections and function symbols.
struct Image {
    bytes: Vec<u8>,
    /// (address, file offset, size) of each section with contents.
    sections: Vec<(u32, usize, u32)>,
    /// (name, address without the Thumb bit, size).
    symbols: Vec<(String, u32, u32)>,
}

impl Image {
    fn parse(bytes: Vec<u8>) -> Self {
        assert_eq!(bytes.get(0..4), Some(&b"\x7fELF"[..]), "not an ELF file");
        let header = |at| u32_at(&bytes, at).unwrap_or_else(|| panic!("short ELF header"));
        let shoff = header(0x20) as usize;
        let shentsize = usize::from(u16_at(&bytes, 0x2e).unwrap_or(40));
        let shnum = usize::from(u16_at(&bytes, 0x30).unwrap_or(0));
        let section = |i: usize| {
            let at = shoff + i * shentsize;
            let field = |k: usize| u32_at(&bytes, at + 4 * k).unwrap_or(0);
            // type, addr, offset, size, link
            (
                field(1),
                field(3),
                field(4) as usize,
                field(5),
                field(6) as usize,
            )
        };
        let mut sections = Vec::new();
        let mut symbols = Vec::new();
        for i in 0..shnum {
            let (kind, addr, offset, size, link) = section(i);
            if kind == 1 {
                sections.push((addr, offset, size));
            }
            if kind == 2 {
                let (_, _, strtab, _, _) = section(link);
                for entry in (offset..offset + size as usize).step_by(16) {
                    let name_at = strtab + u32_at(&bytes, entry).unwrap_or(0) as usize;
                    let name_end = bytes[name_at..]
                        .iter()
                        .position(|&b| b == 0)
                        .map_or(name_at, |n| name_at + n);
                    let name = String::from_utf8_lossy(&bytes[name_at..name_end]).into_owned();
                    let value = u32_at(&bytes, entry + 4).unwrap_or(0) & !1;
                    let size = u32_at(&bytes, entry + 8).unwrap_or(0);
                    let is_function = bytes.get(entry + 12).is_some_and(|info| info & 0xf == 2);
                    if is_function {
                        symbols.push((name, value, size));
                    }
                }
            }
        }
        Image {
            bytes,
            sections,
            symbols,
        }
    }

    fn offset_of(&self, address: u32) -> Option<usize> {
        self.sections
            .iter()
            .find(|(addr, _, size)| address >= *addr && address - *addr < *size)
            .map(|(addr, offset, _)| offset + (address - addr) as usize)
    }

    fn word(&self, address: u32) -> Option<u32> {
        u32_at(&self.bytes, self.offset_of(address)?)
    }

    fn halfword(&self, address: u32) -> Option<u16> {
        u16_at(&self.bytes, self.offset_of(address)?)
    }

    fn function(&self, matches: impl Fn(&str) -> bool) -> (String, u32, u32) {
        let found: Vec<_> = self.symbols.iter().filter(|(n, ..)| matches(n)).collect();
        assert_eq!(found.len(), 1, "expected one such function: {found:?}");
        found[0].clone()
    }

    /// The literal address each store of the function writes to (`None` for
    /// a base not loaded from the pool), in order, up to its first call or
    /// its end; and whether a call ended the walk.
    fn stores_before_any_call(&self, start: u32, size: u32) -> (Vec<Option<u32>>, bool) {
        let mut base: [Option<u32>; 8] = [None; 8];
        let mut stores = Vec::new();
        let mut pc = start;
        while pc < start + size {
            let Some(hw) = self.halfword(pc) else { break };
            if matches!(hw >> 11, 0b11101..=0b11111) {
                let hw2 = self.halfword(pc + 2).unwrap_or(0);
                if hw & 0xf800 == 0xf000 && hw2 & 0xd000 == 0xd000 {
                    return (stores, true);
                }
                if hw & 0xfff0 == 0xf8c0 {
                    let rn = usize::from(hw & 0xf);
                    stores.push(base.get(rn).copied().flatten());
                }
                // MOVW / MOVT Rd, #imm16 (T3): how an image built for speed
                // forms an address, where one built for size loads it from
                // the literal pool.
                let movw = hw & 0xfbf0 == 0xf240;
                let movt = hw & 0xfbf0 == 0xf2c0;
                if (movw || movt) && hw2 & 0x8000 == 0 {
                    let imm16 = (u32::from(hw & 0xf) << 12)
                        | (u32::from((hw >> 10) & 1) << 11)
                        | (u32::from((hw2 >> 12) & 7) << 8)
                        | u32::from(hw2 & 0xff);
                    let rd = usize::from((hw2 >> 8) & 0xf);
                    if let Some(slot) = base.get_mut(rd) {
                        *slot = if movw {
                            Some(imm16)
                        } else {
                            slot.map(|low| (low & 0xffff) | (imm16 << 16))
                        };
                    }
                }
                pc += 4;
                continue;
            }
            if hw == 0x4770 {
                break;
            }
            let low_reg = |shift: u16| usize::from((hw >> shift) & 7);
            match hw & 0xf800 {
                // LDR Rt, [PC, #imm8 * 4]
                0x4800 => {
                    let literal = ((pc + 4) & !3) + u32::from(hw & 0xff) * 4;
                    base[low_reg(8)] = self.word(literal);
                }
                // STR Rt, [Rn, #imm5 * 4]
                0x6000 => stores.push(base[low_reg(3)]),
                // LDR Rt, [Rn, #imm5 * 4]: Rt no longer holds a literal.
                0x6800 => base[low_reg(0)] = None,
                // MOVS Rd, #imm8
                0x2000 => base[low_reg(8)] = None,
                _ => {}
            }
            pc += 2;
        }
        (stores, false)
    }
}

#[test]
fn the_stm32_image_drops_the_enable_first() {
    for (path, image) in images() {
        eprintln!("{}", path.display());
        drops_the_enable_first(&image);
    }
}

fn drops_the_enable_first(image: &Image) {
    let (name, start, size) = image.function(|n| n == "__pre_init");
    let (stores, called) = image.stores_before_any_call(start, size.max(2));
    assert!(!called, "{name} calls before RAM is initialised");
    let bsrr = stores.iter().position(|s| *s == Some(GPIOE_BSRR));
    let moder = stores.iter().position(|s| *s == Some(GPIOE_MODER));
    assert!(
        matches!((bsrr, moder), (Some(b), Some(m)) if b < m),
        "{name} must set PE15's latch low (BSRR) and then make it an output (MODER): stores {stores:x?}"
    );

    for (what, matches) in [
        (
            "the panic handler",
            Box::new(|n: &str| n.contains("rust_begin_unwind")) as Box<dyn Fn(&str) -> bool>,
        ),
        (
            "HardFault",
            Box::new(|n: &str| n.contains("__cortex_m_rt_HardFault")),
        ),
        (
            "the default handler",
            Box::new(|n: &str| n == "DefaultHandler"),
        ),
        (
            "MemManage (the stack guard)",
            Box::new(|n: &str| n == "MemoryManagement"),
        ),
    ] {
        let (name, start, size) = image.function(matches);
        let (stores, _) = image.stores_before_any_call(start, size);
        assert_eq!(
            stores.first(),
            Some(&Some(GPIOE_BSRR)),
            "{what} ({name}) must drop the enable (a store to GPIOE_BSRR) before anything else: stores before its first call {stores:x?}"
        );
    }
}

/// The RTT log never waits for the probe (defmt-rtt's `disable-blocking-mode`):
/// its blocking writer, which spins with interrupts masked while the buffer
/// is full, is not in the image at all.
#[test]
fn the_stm32_log_never_blocks() {
    for (path, image) in images() {
        let writers: Vec<_> = image
            .symbols
            .iter()
            .filter(|(n, ..)| n.contains("blocking_write"))
            .map(|(n, ..)| n.clone())
            .collect();
        assert!(
            writers.iter().all(|n| n.contains("nonblocking_write")),
            "{}: a blocking RTT writer is linked: {writers:?}",
            path.display()
        );
    }
}
