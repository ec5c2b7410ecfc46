//! SIGINT / SIGTERM (included by main.rs only): the first one asks a running render
//! to stop after its current sample wave and write what it has; a second one ends
//! the process at once, writing nothing more (outputs are written whole or not at
//! all, so no half file is left either way).

use std::sync::atomic::{AtomicBool, Ordering};

/// Exit code of a render that was interrupted (128 + SIGINT, as shells report it).
pub(crate) const EXIT_CODE: i32 = 130;

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Installs the handler (once; later calls do nothing).
pub(crate) fn install() {
    let _ = ctrlc::set_handler(|| {
        if REQUESTED.swap(true, Ordering::SeqCst) {
            eprintln!("arbor: interrupted again: stopping now");
            std::process::exit(EXIT_CODE);
        }
        eprintln!("arbor: interrupted: finishing the current sample wave, then writing the image so far");
    });
}

/// Whether a signal asked the render to stop.
pub(crate) fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}
