//! `yosemitech measure conductivity`: the manual's procedure with progress bars.

use std::cell::RefCell;
use std::io::Write;
use std::rc::Rc;
use std::time::Duration;

use indicatif::ProgressBar;
use serde_json::json;
use yosemitech::conductivity;
use yosemitech::procedures::conductivity::{Measurement, MeasurementConfig, MeasurementEvent, measure};
use yosemitech::procedures::{RealSleep, Sleep};

use crate::catalog::Catalog;
use crate::cli::{Global, MeasureConductivityArgs};
use crate::device::{is_typed, procedure_failed};
use crate::error::{CliError, Result};
use crate::format::f32_json;
use crate::port::{self, Opened};
use crate::progress;

/// The bars of a running measurement.
#[derive(Default)]
struct Bars {
    warm_up: Option<ProgressBar>,
    readings: Option<ProgressBar>,
}

/// A [`Sleep`] that fills the warm-up bar while it waits.
struct ProgressSleep<S> {
    inner: S,
    bars: Rc<RefCell<Bars>>,
}

impl<S: Sleep> Sleep for ProgressSleep<S> {
    fn sleep(&mut self, duration: Duration) {
        let warm_up = self.bars.borrow_mut().warm_up.take();
        match warm_up {
            Some(bar) => progress::wait(&bar, duration, |d| self.inner.sleep(d), || true),
            None => self.inner.sleep(duration),
        }
    }
}

/// Runs the measurement procedure on the probe at `slave`, with progress
/// bars on stderr (hidden when it is not a terminal).
pub fn run_procedure(
    opened: &mut Opened,
    slave: u8,
    config: &MeasurementConfig,
    sleep: impl Sleep,
) -> Result<Measurement> {
    let ctx = opened.context(slave, "the measurement");
    let bars = Rc::new(RefCell::new(Bars::default()));
    let mut sleeper = ProgressSleep { inner: sleep, bars: Rc::clone(&bars) };
    let events_bars = Rc::clone(&bars);
    let mut events = move |event: MeasurementEvent| {
        let mut bars = events_bars.borrow_mut();
        match event {
            MeasurementEvent::WarmingUp { warm_up } => {
                bars.warm_up = Some(progress::timer(warm_up, "warming up"));
            }
            MeasurementEvent::Reading { accepted, needed, reading, valid } => {
                let bar = bars
                    .readings
                    .get_or_insert_with(|| progress::bar(needed as u64, "{msg:24} [{bar:30}] {pos}/{len} readings"));
                bar.set_position(accepted as u64);
                bar.set_message(if valid {
                    format!("{} mS/cm", reading.conductivity_ms_cm)
                } else {
                    "range-switch error".to_owned()
                });
            }
        }
    };
    let mut probe = conductivity::Device::new(&mut opened.bus, slave);
    let result = measure(&mut probe, config, &mut sleeper, &mut events);
    let bars = bars.borrow();
    for bar in bars.warm_up.iter().chain(&bars.readings) {
        bar.finish_and_clear();
    }
    result.map_err(|e| procedure_failed(&e, &ctx))
}

/// The procedure's timing from the hidden test options.
fn config(args: &MeasureConductivityArgs) -> Result<MeasurementConfig> {
    let mut config = MeasurementConfig::default();
    if args.fast {
        config.warm_up = Duration::ZERO;
        config.interval = Duration::ZERO;
    }
    config.warm_up = args.warm_up.unwrap_or(config.warm_up);
    config.interval = args.interval.unwrap_or(config.interval);
    if let Some(n) = args.readings {
        if n == 0 {
            return Err(CliError::usage("--readings 0 averages nothing").hint("the manual averages 10 readings"));
        }
        config.readings = n;
        config.max_reads = n * 2;
    }
    Ok(config)
}

/// Runs `measure conductivity`.
pub fn run(catalog: &Catalog, global: &Global, args: &MeasureConductivityArgs, out: &mut dyn Write) -> Result<()> {
    let entry = catalog.entry("conductivity")?;
    if !is_typed(entry, "conductivity") {
        return Err(CliError::usage("`measure conductivity` needs the built-in conductivity sensor")
            .hint("a --spec file replaced it; run without --spec, or use `yosemitech poll` for the --spec sensor"));
    }
    let config = config(args)?;
    let slave = args.address.get(entry.sensor.default_address)?;
    let mut opened = port::open(&args.port, global, &entry.sensor.serial)?;
    let m = run_procedure(&mut opened, slave, &config, RealSleep)?;
    if args.json {
        let doc = json!({
            "conductivity_ms_cm": f32_json(m.conductivity_ms_cm),
            "temperature_c": f32_json(m.temperature_c),
            "tds_mg_l": f32_json(m.tds_mg_l),
            "readings": m.readings,
            "discarded": m.discarded,
        });
        writeln!(out, "{doc}")?;
    } else {
        show(&m, None, out)?;
    }
    Ok(())
}

/// The result, with units; `digits` rounds the conductivity to that many
/// decimals (and the rest to match), `None` shows every digit.
pub fn show(m: &Measurement, digits: Option<usize>, out: &mut dyn Write) -> Result<()> {
    let num = |v: f32, extra: isize| match digits {
        Some(d) => format!("{v:.*}", d.saturating_add_signed(extra)),
        None => v.to_string(),
    };
    writeln!(out, "  conductivity  {} mS/cm (mean of {} readings)", num(m.conductivity_ms_cm, 0), m.readings)?;
    writeln!(out, "  temperature   {} °C", num(m.temperature_c, -2))?;
    writeln!(out, "  TDS           {} mg/L (mean uS/cm x {})", num(m.tds_mg_l, -3), conductivity::TDS_MG_L_PER_US_CM)?;
    if m.discarded > 0 {
        writeln!(out, "  discarded     {} readings with a range-switch error", m.discarded)?;
    }
    Ok(())
}
