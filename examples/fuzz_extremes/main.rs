//! The numeric-extremes property run (issue 28, point 6): random small
//! scenes pushed to extreme scales, offsets, point-light distances, camera
//! distances and near/far planes (10⁻⁶ … 10³⁰), with slivers, coincident
//! and near-coincident copies and large triangle counts, rendered by the
//! CPU twin exactly as `izb render` does (`Scene::new`, which enforces the
//! precision envelope, then the BVH and the IZB with edge surfaces).
//!
//! The rule for every case: a named error, or the right masks —
//! 1. exact mode agrees with the same scene *rescaled into the comfortable
//!    range* (the twin: the inputs the renderer was handed, `f64`-rounded,
//!    with the similarity undone; the relative extremes kept) sample for
//!    sample, pixels tested and samples counted included, except samples
//!    within float rounding of a boundary (`decision_margin` below
//!    `FLOAT_DECISION_TOLERANCE`, counted, as the same-sample tests do);
//! 2. exact mode agrees the same way with the `f64` extended same-sample
//!    reference (of the twin, or of the scene itself where the twin is
//!    refused);
//! 3. LUT mode differs from exact mode only at samples within the LUT's
//!    proven misclassification bound (plus `LOOKUP_SLACK`) of an occluder's
//!    edge (Wyman et al. 2015, §4), or within float rounding;
//! 4. a power-of-two scale, which `f64` and `f32` represent exactly, gives
//!    masks bit-identical to the twin's;
//! 5. the inputs' own rounding (what the envelope's `MAX_ORIGIN_RADII`
//!    bounds): the twin's exact masks agree with those of the generator's
//!    unrounded scene within float rounding, on samples both count on the
//!    same surface. A sample ray that found another surface once the
//!    inputs rounded (near-coincident copies 10⁻¹⁵ apart, an edge within
//!    the rounding) is counted as moved, not compared: primary visibility
//!    is exact on either scene, and the two scenes differ.
//!
//! A panic, a case running past `--hang-seconds` (a watchdog prints it and
//! aborts) or a broken rule fails the run; each failing case prints the
//! command that replays it alone. Prints how many cases were refused and
//! why, by class, and the measured envelope: the extreme scales, offsets
//! and light distances at which accepted cases agreed.
//!
//! `cargo run --release --example fuzz_extremes -- [--cases N] [--seconds S]
//! [--seed K] [--threads T] [--hang-seconds H] [--case I]`; CI runs it for a
//! bounded time with a printed seed.

mod check;
mod generate;

use check::{check_case, Outcome, Tally};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

struct Args {
    cases: u64,
    seconds: f64,
    seed: u64,
    threads: usize,
    hang_seconds: f64,
    case: Option<u64>,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        cases: u64::MAX,
        seconds: f64::INFINITY,
        seed: 1,
        threads: 2,
        hang_seconds: 60.0,
        case: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().ok_or(format!("{flag} needs a value"))?;
        let number = || {
            value
                .parse::<f64>()
                .map_err(|e| format!("{flag} {value}: {e}"))
        };
        match flag.as_str() {
            "--cases" => a.cases = number()? as u64,
            "--seconds" => a.seconds = number()?,
            "--seed" => a.seed = number()? as u64,
            "--threads" => a.threads = (number()? as usize).max(1),
            "--hang-seconds" => a.hang_seconds = number()?,
            "--case" => a.case = Some(number()? as u64),
            other => return Err(format!("unknown flag {other}")),
        }
    }
    if a.cases == u64::MAX && a.seconds.is_infinite() && a.case.is_none() {
        a.cases = 1000;
    }
    Ok(a)
}

/// What the workers share: the next case, the running cases' start
/// times (for the watchdog) and the tally.
struct Shared {
    next: AtomicU64,
    running: Mutex<Vec<Option<(u64, Instant)>>>,
    tally: Mutex<Tally>,
}

fn main() {
    let a = args().unwrap_or_else(|e| {
        eprintln!("fuzz_extremes: {e}");
        std::process::exit(2)
    });
    let (first, last) = match a.case {
        Some(i) => (i, i + 1),
        None => (0, a.cases),
    };
    println!(
        "fuzz_extremes: seed {}, {} threads, {}",
        a.seed,
        a.threads,
        match a.case {
            Some(i) => format!("case {i} alone"),
            None if a.cases == u64::MAX => format!("for {} s", a.seconds),
            None => format!("{} cases (at most {} s)", a.cases, a.seconds),
        }
    );
    // The panics are caught and reported per case; the default hook would
    // print each one's backtrace line as well.
    if a.case.is_none() {
        std::panic::set_hook(Box::new(|_| {}));
    }
    let shared = Shared {
        next: AtomicU64::new(first),
        running: Mutex::new(vec![None; a.threads]),
        tally: Mutex::new(Tally::default()),
    };
    let start = Instant::now();
    let deadline = start + Duration::from_secs_f64(a.seconds.min(1e9));
    let hang = Duration::from_secs_f64(a.hang_seconds);
    let seed = a.seed;
    let done = AtomicU64::new(0);
    std::thread::scope(|scope| {
        for worker in 0..a.threads {
            let shared = &shared;
            let done = &done;
            scope.spawn(move || loop {
                let i = shared.next.fetch_add(1, Ordering::SeqCst);
                if i >= last || Instant::now() >= deadline {
                    break;
                }
                shared.running.lock().unwrap()[worker] = Some((i, Instant::now()));
                let case = generate::case(seed, i);
                let outcome = std::panic::catch_unwind(|| check_case(&case))
                    .unwrap_or_else(|p| Outcome::Panic(panic_text(p)));
                shared.running.lock().unwrap()[worker] = None;
                let failed = shared.tally.lock().unwrap().add(&case, &outcome);
                if let Some(why) = failed {
                    eprintln!(
                        "FAIL case {i} ({}): {why}\n  replay: cargo run --release --example \
                         fuzz_extremes -- --seed {seed} --case {i}",
                        case.describe()
                    );
                }
                done.fetch_add(1, Ordering::SeqCst);
            });
        }
        // The watchdog: a case running past the hang limit ends the run.
        let (shared, done) = (&shared, &done);
        scope.spawn(move || loop {
            std::thread::sleep(Duration::from_millis(250));
            if shared.running.lock().unwrap().iter().all(Option::is_none)
                && (shared.next.load(Ordering::SeqCst) >= last || Instant::now() >= deadline)
            {
                break;
            }
            let running = shared.running.lock().unwrap().clone();
            for (i, since) in running.into_iter().flatten() {
                if since.elapsed() > hang {
                    let case = generate::case(seed, i);
                    eprintln!(
                        "HANG: case {i} ({}) ran over {hang:?}\n  replay: cargo run --release \
                         --example fuzz_extremes -- --seed {seed} --case {i}",
                        case.describe()
                    );
                    eprintln!("{} cases done before it", done.load(Ordering::SeqCst));
                    std::process::exit(1);
                }
            }
        });
    });
    let tally = shared.tally.into_inner().unwrap();
    tally.print(start.elapsed().as_secs_f64(), seed);
    if tally.failures() > 0 {
        std::process::exit(1);
    }
}

fn panic_text(p: Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "(no message)".into())
}

/// Counts by key, printed largest first.
pub fn print_counts(title: &str, counts: &BTreeMap<String, u64>) {
    let mut rows: Vec<_> = counts.iter().collect();
    rows.sort_by_key(|r| std::cmp::Reverse(*r.1));
    println!("{title}:");
    for (what, n) in rows {
        println!("  {n:>9}  {what}");
    }
}
