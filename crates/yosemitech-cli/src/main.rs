//! `yosemitech`: the field tool for Yosemitech water-quality probes on Modbus RTU.
//! See the library, `yosemitech_cli`.

fn main() -> std::process::ExitCode {
    yosemitech_cli::main()
}
