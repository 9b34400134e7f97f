//! Generates the codecs of this crate's own spec files (`spec/`) into
//! `OUT_DIR`, as a build script calls prost-build for its `.proto` files.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out_dir = std::env::var_os("OUT_DIR").ok_or("cargo sets OUT_DIR")?;
    yosemitech_codegen::Config::new().std_feature(None).compile("spec", out_dir)?;
    Ok(())
}
