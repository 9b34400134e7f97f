//! `yosemitech._native`: the Python package's native module. It exposes the
//! library the CLI and the station share (`yosemitech-ops`), not a second
//! implementation: the spec's sensors, one request of a spec command, the
//! scan's identification, and the simulator. Python sees values, dicts of
//! values and exceptions; the port is driven with the GIL released.

#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use yosemitech_ops::bus::AnyClient;
use yosemitech_ops::{Identifier, TransactionError, printable, target};
use yosemitech_rtu::{ClientConfig, Error as RtuError, FrameError, RetryPolicy};
use yosemitech_sim::{ServeConfig, Server, serve_tcp};
use yosemitech_spec::lookup::{Lookup, find_sensor};
use yosemitech_spec::{CommandSpec, Sensor, Value};

create_exception!(_native, YosemitechError, PyException, "Every error of this package.");
create_exception!(
    _native,
    SpecError,
    YosemitechError,
    "A spec file that does not load: each problem with its file, line and column."
);
create_exception!(_native, UnknownError, YosemitechError, "A sensor or command the loaded spec does not have.");
create_exception!(
    _native,
    RequestError,
    YosemitechError,
    "A request that cannot be built: a value out of its field's range, a field missing."
);
create_exception!(
    _native,
    BusError,
    YosemitechError,
    "No valid reply: the port failed, or what came back was not the reply."
);
create_exception!(_native, NoReply, BusError, "No reply within the timeout, after the retries.");
create_exception!(_native, CrcError, BusError, "A reply whose CRC is wrong, after the retries.");
create_exception!(
    _native,
    ExceptionReply,
    BusError,
    "The probe answered with a Modbus exception; args: (message, code)."
);
create_exception!(_native, DecodeError, YosemitechError, "A reply that is not as the command's fields say.");

/// The sensors loaded: the built-in spec, then spec files given at run time.
static CATALOG: Mutex<Vec<Arc<Sensor>>> = Mutex::new(Vec::new());

fn catalog() -> PyResult<MutexGuard<'static, Vec<Arc<Sensor>>>> {
    let mut sensors = CATALOG.lock().unwrap_or_else(PoisonError::into_inner);
    if sensors.is_empty() {
        let spec = yosemitech_ops::built_in::load()
            .map_err(|d| SpecError::new_err(format!("the built-in spec does not load:\n{d}")))?;
        *sensors = spec.sensors.into_iter().map(Arc::new).collect();
    }
    Ok(sensors)
}

/// The loaded sensor `name` names, as the CLI finds it: by name (`-` for
/// `_`) or by model, with the closest name suggested.
fn sensor(name: &str) -> PyResult<Arc<Sensor>> {
    let sensors = catalog()?;
    let refs: Vec<&Sensor> = sensors.iter().map(|s| s.as_ref()).collect();
    match find_sensor(&refs, name) {
        Lookup::Found { index, .. } => {
            sensors.get(index).cloned().ok_or_else(|| UnknownError::new_err(format!("no sensor `{name}`")))
        }
        Lookup::SameModel(indices) => {
            let names: Vec<&str> = indices.iter().filter_map(|&i| refs.get(i).map(|s| s.name.as_str())).collect();
            Err(UnknownError::new_err(format!("model `{name}` is {} sensors: {}", names.len(), names.join(", "))))
        }
        Lookup::Unknown { closest } => Err(UnknownError::new_err(match closest {
            Some(closest) => format!("no sensor `{name}` in the loaded spec; did you mean `{closest}`?"),
            None => format!("no sensor `{name}` in the loaded spec"),
        })),
    }
}

fn command<'s>(sensor: &'s Sensor, name: &str) -> PyResult<&'s CommandSpec> {
    let wanted = name.replace('-', "_");
    sensor
        .commands
        .iter()
        .find(|c| c.name == wanted)
        .ok_or_else(|| UnknownError::new_err(format!("sensor `{}` has no command `{name}`", sensor.name)))
}

/// Loads the sensors of a spec file (or a directory of them), replacing
/// built-in sensors of the same name; returns their names.
#[pyfunction]
fn load_spec(path: PathBuf) -> PyResult<Vec<String>> {
    let spec = yosemitech_ops::built_in::load_file(&path)
        .map_err(|d| SpecError::new_err(format!("{} does not load:\n{d}", path.display())))?;
    let mut sensors = catalog()?;
    let mut names = Vec::new();
    for loaded in spec.sensors {
        names.push(loaded.name.clone());
        match sensors.iter_mut().find(|s| s.name == loaded.name) {
            Some(existing) => *existing = Arc::new(loaded),
            None => sensors.push(Arc::new(loaded)),
        }
    }
    Ok(names)
}

/// Every loaded sensor: its name, title, models, address and serial
/// settings, and its commands with their fields, units and ranges.
#[pyfunction]
fn sensors(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let list = PyList::empty(py);
    for sensor in catalog()?.iter() {
        let s = PyDict::new(py);
        s.set_item("name", &sensor.name)?;
        s.set_item("title", &sensor.title)?;
        s.set_item("model", &sensor.model)?;
        s.set_item("model_code", &sensor.model_code)?;
        s.set_item("default_address", sensor.default_address)?;
        s.set_item("baud", sensor.serial.baud)?;
        let commands = PyList::empty(py);
        for c in &sensor.commands {
            let d = PyDict::new(py);
            d.set_item("name", &c.name)?;
            d.set_item("read", c.is_read())?;
            d.set_item("trigger", c.trigger)?;
            d.set_item("role", c.role.map(yosemitech_spec::Role::name))?;
            d.set_item("fixed_address", c.fixed_slave)?;
            d.set_item("register", c.address)?;
            d.set_item("count", c.count)?;
            let fields = PyList::empty(py);
            for f in c.named_fields() {
                let fd = PyDict::new(py);
                fd.set_item("name", f.display_name())?;
                fd.set_item("unit", &f.unit)?;
                fd.set_item("min", f.range.map(|(min, _)| min))?;
                fd.set_item("max", f.range.map(|(_, max)| max))?;
                fields.append(fd)?;
            }
            d.set_item("fields", fields)?;
            commands.append(d)?;
        }
        s.set_item("commands", commands)?;
        list.append(s)?;
    }
    Ok(list)
}

fn value_to_py<'py>(py: Python<'py>, value: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        Value::Float(f) => f64::from(*f).into_pyobject(py)?.into_any(),
        Value::Int(i) => i.into_pyobject(py)?.into_any(),
        Value::Text(t) => t.into_pyobject(py)?.into_any(),
        Value::Version(v) => v.to_string().into_pyobject(py)?.into_any(),
        Value::Bcd(b) => b.to_string().into_pyobject(py)?.into_any(),
        Value::Enum { name: Some(name), .. } => name.into_pyobject(py)?.into_any(),
        Value::Enum { raw, name: None } => raw.into_pyobject(py)?.into_any(),
    })
}

fn transaction_error(error: TransactionError, last_reply: &[u8]) -> PyErr {
    let text = format!("{}: {error}", error.command());
    match error {
        TransactionError::Request { .. } => RequestError::new_err(text),
        TransactionError::Decode { .. } => DecodeError::new_err(text),
        TransactionError::Bus { error, command } => {
            let text = format!("{command}: {}", yosemitech_ops::failure_text(&error, last_reply));
            match error {
                RtuError::Timeout { .. } => NoReply::new_err(text),
                RtuError::Frame { error: FrameError::Crc { .. } } => CrcError::new_err(text),
                RtuError::Frame { error: FrameError::Exception { code, .. } } => {
                    ExceptionReply::new_err((text, code.to_u8()))
                }
                _ => BusError::new_err(text),
            }
        }
    }
}

/// A bus: a serial port (`/dev/ttyUSB0`) or an RTU-over-TCP gateway
/// (`tcp://host:port`), with a timeout per reply and retries.
#[pyclass(module = "yosemitech._native")]
struct Bus {
    client: Mutex<AnyClient>,
}

impl Bus {
    fn client(&self) -> MutexGuard<'_, AnyClient> {
        self.client.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

#[pymethods]
impl Bus {
    /// Opens `port` at `baud` (the loaded sensors' usual rate when omitted).
    #[new]
    #[pyo3(signature = (port, baud = None, timeout = 1.0, retries = 2))]
    fn new(py: Python<'_>, port: &str, baud: Option<u32>, timeout: f64, retries: u32) -> PyResult<Self> {
        let timeout = Duration::try_from_secs_f64(timeout).ok().filter(|t| !t.is_zero()).ok_or_else(|| {
            pyo3::exceptions::PyValueError::new_err(format!("timeout {timeout} is not a time in seconds"))
        })?;
        let mut serial = yosemitech_ops::common_serial(catalog()?.iter().map(|s| s.as_ref()));
        if let Some(baud) = baud {
            serial.baud = baud;
        }
        let config = ClientConfig {
            timeout,
            retry: RetryPolicy { retries, ..RetryPolicy::default() },
            ..ClientConfig::default()
        };
        let client = py
            .detach(|| yosemitech_ops::bus::open(port, serial, config))
            .map_err(|e| BusError::new_err(format!("cannot open {port}: {e}")))?;
        Ok(Self { client: Mutex::new(client) })
    }

    /// Reads `command` of `sensor` at `address` and returns the reply's
    /// fields by name. Writes are refused here: a write to a probe comes
    /// with range checks, a backup and a read-back, which the calibration
    /// session of the library will bring to Python.
    fn read<'py>(&self, py: Python<'py>, sensor: &str, command: &str, address: u8) -> PyResult<Bound<'py, PyDict>> {
        let spec = self::sensor(sensor)?;
        let command = self::command(&spec, command)?;
        if !command.is_read() {
            return Err(RequestError::new_err(format!(
                "{} is a write: this package reads only (the yosemitech tool writes, with a backup and a read-back)",
                command.name
            )));
        }
        let result = py.detach(|| {
            let mut client = self.client();
            yosemitech_ops::call(&mut client, command, target(command, address), &BTreeMap::new())
                .map_err(|e| (e, client.last_reply().to_vec()))
        });
        let fields = result.map_err(|(e, reply)| transaction_error(e, &reply))?;
        let dict = PyDict::new(py);
        for (name, value) in &fields {
            dict.set_item(name, value_to_py(py, value)?)?;
        }
        Ok(dict)
    }

    /// Identifies what answers at each of `addresses` as `yosemitech scan`
    /// does; one dict per device found.
    #[pyo3(signature = (addresses = None))]
    fn scan<'py>(&self, py: Python<'py>, addresses: Option<Vec<u8>>) -> PyResult<Bound<'py, PyList>> {
        let loaded: Vec<Arc<Sensor>> = catalog()?.clone();
        let addresses = addresses.unwrap_or_else(|| (1..=247).collect());
        let identifier = Identifier::new(loaded.iter().map(|s| s.as_ref()));
        let found = py.detach(|| {
            let mut client = self.client();
            let mut found = Vec::new();
            for &address in &addresses {
                match identifier.identify(&mut client, address) {
                    Ok(Some(f)) => found.push(f),
                    Ok(None) => {}
                    Err(e) => return Err((e, client.last_reply().to_vec())),
                }
            }
            Ok(found)
        });
        let found = found.map_err(|(e, reply)| transaction_error(e, &reply))?;
        let list = PyList::empty(py);
        for f in found {
            let d = PyDict::new(py);
            d.set_item("address", f.address)?;
            d.set_item("sensor", f.identified.map(|s| &s.name))?;
            d.set_item("candidates", f.candidates.iter().map(|s| &s.name).collect::<Vec<_>>())?;
            d.set_item("serial_number", f.serial_number.as_deref().map(printable))?;
            d.set_item("model_code", f.model_code)?;
            d.set_item("models", f.models)?;
            d.set_item("hardware", f.hardware.map(|v| v.to_string()))?;
            d.set_item("software", f.software.map(|v| v.to_string()))?;
            d.set_item("manual_software", f.manual.and_then(|m| m.software.as_deref()))?;
            d.set_item("reason", f.reason)?;
            list.append(d)?;
        }
        Ok(list)
    }
}

/// A probe simulated from its spec, served over TCP (RTU frames, as a
/// gateway), so that code written for a probe runs without one.
#[pyclass(module = "yosemitech._native")]
struct Simulator {
    server: Mutex<Option<Server<yosemitech_sim::Simulator>>>,
    url: String,
}

#[pymethods]
impl Simulator {
    /// Serves a simulated `sensor` at `address` (its factory address when
    /// omitted) on a free loopback port.
    #[new]
    #[pyo3(signature = (sensor, address = None))]
    fn new(sensor: &str, address: Option<u8>) -> PyResult<Self> {
        let spec = self::sensor(sensor)?;
        let address = address.unwrap_or(spec.default_address);
        let simulator = yosemitech_sim::Simulator::new(spec).with_address(address);
        let server = serve_tcp(simulator, "127.0.0.1:0", ServeConfig::default())
            .map_err(|e| BusError::new_err(format!("cannot serve the simulator: {e}")))?;
        let url = server.local_addr().map(|a| format!("tcp://{a}")).unwrap_or_default();
        Ok(Self { server: Mutex::new(Some(server)), url })
    }

    /// `tcp://127.0.0.1:PORT`: what [`Bus`] opens.
    #[getter]
    fn url(&self) -> &str {
        &self.url
    }

    /// The fields `command` holds now, by name: what a read returns.
    fn values<'py>(&self, py: Python<'py>, command: &str) -> PyResult<Bound<'py, PyDict>> {
        let server = self.server.lock().unwrap_or_else(PoisonError::into_inner);
        let server = server.as_ref().ok_or_else(|| BusError::new_err("the simulator is stopped"))?;
        let values = server.device().values(command).map_err(|e| UnknownError::new_err(e.to_string()))?;
        let dict = PyDict::new(py);
        for (name, value) in &values {
            dict.set_item(name, value_to_py(py, value)?)?;
        }
        Ok(dict)
    }

    /// Stops serving.
    fn stop(&self) -> PyResult<()> {
        let server = self.server.lock().unwrap_or_else(PoisonError::into_inner).take();
        match server {
            Some(server) => server.stop().map_err(|e| BusError::new_err(format!("stopping the simulator: {e}"))),
            None => Ok(()),
        }
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, _args: &Bound<'_, pyo3::types::PyTuple>) -> PyResult<bool> {
        self.stop()?;
        Ok(false)
    }
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_function(wrap_pyfunction!(sensors, m)?)?;
    m.add_function(wrap_pyfunction!(load_spec, m)?)?;
    m.add_class::<Bus>()?;
    m.add_class::<Simulator>()?;
    m.add("YosemitechError", py.get_type::<YosemitechError>())?;
    m.add("SpecError", py.get_type::<SpecError>())?;
    m.add("UnknownError", py.get_type::<UnknownError>())?;
    m.add("RequestError", py.get_type::<RequestError>())?;
    m.add("BusError", py.get_type::<BusError>())?;
    m.add("NoReply", py.get_type::<NoReply>())?;
    m.add("CrcError", py.get_type::<CrcError>())?;
    m.add("ExceptionReply", py.get_type::<ExceptionReply>())?;
    m.add("DecodeError", py.get_type::<DecodeError>())?;
    Ok(())
}
