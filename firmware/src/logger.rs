//! A panic-free defmt global logger over semihosting stdout.
//!
//! defmt-semihosting panics on misuse (re-entrant acquire), a path the compiler cannot
//! prove dead, which would fail the image's link-time panic check. This logger never
//! panics: the image is single-threaded and uses no interrupts, and a nested `acquire`
//! (which cannot happen here) drops the nested frame instead.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU8, Ordering};
use cortex_m_semihosting::hio::{self, HostStream};

#[defmt::global_logger]
struct Logger;

struct State {
    encoder: defmt::Encoder,
    out: Option<HostStream>,
    opened: bool,
}

struct Shared(UnsafeCell<State>);

// SAFETY: only reached between `acquire` and `release` at depth 1, with interrupts off,
// on a single core: never two references at once.
#[allow(unsafe_code)]
unsafe impl Sync for Shared {}

static STATE: Shared = Shared(UnsafeCell::new(State {
    encoder: defmt::Encoder::new(),
    out: None,
    opened: false,
}));

/// Nesting depth of `acquire`; only depth 1 writes.
static DEPTH: AtomicU8 = AtomicU8::new(0);

fn with_state(f: impl FnOnce(&mut State)) {
    if DEPTH.load(Ordering::Relaxed) == 1 {
        // SAFETY: see `Shared`: depth 1, interrupts off, single core.
        #[allow(unsafe_code)]
        let state = unsafe { &mut *STATE.0.get() };
        f(state);
    }
}

fn emit(out: &mut Option<HostStream>, bytes: &[u8]) {
    if let Some(h) = out.as_mut() {
        let _ = h.write_all(bytes);
    }
}

// SAFETY: acquire/release nest correctly (tracked by DEPTH), and the encoder is used only
// at depth 1 with interrupts disabled.
#[allow(unsafe_code)]
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        cortex_m::interrupt::disable();
        if DEPTH.fetch_add(1, Ordering::Relaxed) == 0 {
            with_state(|s| {
                if !s.opened {
                    s.out = hio::hstdout().ok();
                    s.opened = true;
                }
                let State { encoder, out, .. } = s;
                encoder.start_frame(|b| emit(out, b));
            });
        }
    }

    unsafe fn flush() {}

    unsafe fn release() {
        with_state(|s| {
            let State { encoder, out, .. } = s;
            encoder.end_frame(|b| emit(out, b));
        });
        let _ = DEPTH.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |d| d.checked_sub(1));
        // The image never enables interrupts; leave them off.
    }

    unsafe fn write(bytes: &[u8]) {
        with_state(|s| {
            let State { encoder, out, .. } = s;
            encoder.write(bytes, |b| emit(out, b));
        });
    }
}

/// defmt's panic hook (`defmt::panic!` and friends): report and stop, never unwind.
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    crate::board::exit(102)
}
