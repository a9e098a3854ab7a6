//! The hardware edge of the reference target (QEMU mps2-an500): embedded-hal 1.0 drivers,
//! the task block, the painted stack and the exit path.
//!
//! Every `unsafe` block of the image is in this module, each with its reason.

use core::convert::Infallible;
use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{ErrorType, OutputPin};
use reactionless::block::sectioned_block_len;

/// MPS2 FPGA I/O: the user LEDs register (bits 1:0), AN385/AN500 memory map.
const FPGAIO_LED: *mut u32 = 0x4002_8000 as *mut u32;

/// Core clock of the MPS2 FPGA images (Hz): the unit of [`Delay`].
pub const SYSCLK_HZ: u32 = 25_000_000;

/// One of the two MPS2 user LEDs as an [`OutputPin`] ("planner busy" line).
pub struct Led {
    mask: u32,
}

impl Led {
    /// LED `index` (0 or 1).
    pub fn new(index: u8) -> Self {
        Self {
            mask: 1 << (index & 1),
        }
    }

    fn update(&mut self, on: bool) {
        // SAFETY: FPGAIO_LED is the memory-mapped LED register of the MPS2 FPGA image
        // (always present, word-aligned); volatile read-modify-write, single core, no
        // interrupts touch it.
        #[allow(unsafe_code)]
        unsafe {
            let v = FPGAIO_LED.read_volatile();
            FPGAIO_LED.write_volatile(if on { v | self.mask } else { v & !self.mask });
        }
    }
}

impl ErrorType for Led {
    type Error = Infallible;
}

impl OutputPin for Led {
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.update(true);
        Ok(())
    }

    fn set_low(&mut self) -> Result<(), Infallible> {
        self.update(false);
        Ok(())
    }
}

/// A busy-wait [`DelayNs`] at [`SYSCLK_HZ`]: a fixed instruction loop, so the number of
/// instructions it runs is deterministic.
pub struct Delay;

impl DelayNs for Delay {
    fn delay_ns(&mut self, ns: u32) {
        let cycles = (u64::from(ns) * u64::from(SYSCLK_HZ) / 1_000_000_000) as u32;
        cortex_m::asm::delay(cycles.max(1));
    }
}

// SAFETY (declaration): linker-script symbols; only their addresses are used.
#[allow(unsafe_code)]
unsafe extern "C" {
    static _task_block: u8;
    static _stack_start: u32;
    static _stack_end: u32;
}

/// The task block QEMU's loader placed at `TASK` (see `memory.x`).
pub fn task_block() -> &'static [u8] {
    // SAFETY: `_task_block` is the start of the 64 KiB TASK region of memory.x, which the
    // linker reserves (no section is placed there) and which nothing writes at run time;
    // the longest block (both optional sections) is far below 64 KiB.
    #[allow(unsafe_code)]
    unsafe {
        core::slice::from_raw_parts(
            core::ptr::addr_of!(_task_block),
            sectioned_block_len(7, true, true),
        )
    }
}

/// Deepest stack use so far (bytes): cortex-m-rt painted `_stack_end.._stack_start` with
/// `0xCCCC_CCCC` before `main`; the lowest word no longer painted marks the high-water.
pub fn stack_high_water() -> (u32, u32) {
    // SAFETY: both symbols come from cortex-m-rt's link.x and bound the stack region, which
    // is RAM; reading it word by word with volatile loads is always valid.
    #[allow(unsafe_code)]
    unsafe {
        let top = core::ptr::addr_of!(_stack_start) as usize;
        let bottom = core::ptr::addr_of!(_stack_end) as usize;
        let mut p = bottom;
        while p < top && (p as *const u32).read_volatile() == 0xCCCC_CCCC {
            p += 4;
        }
        ((top - p) as u32, (top - bottom) as u32)
    }
}

/// Ends the emulation with `code` (semihosting `SYS_EXIT`; 0 = success).
pub fn exit(code: i32) -> ! {
    cortex_m_semihosting::debug::exit(if code == 0 {
        cortex_m_semihosting::debug::EXIT_SUCCESS
    } else {
        cortex_m_semihosting::debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::wfi();
    }
}
