//! Builds the C interface to the reference Draco decoder (`draco/shim.cc`)
//! against the system's libdraco (Debian's `libdraco-dev`, which
//! `scripts/setup.sh` installs).
fn main() {
    println!("cargo:rerun-if-changed=draco/shim.cc");
    let include = std::env::var("DRACO_INCLUDE").unwrap_or_else(|_| "/usr/include".into());
    if !std::path::Path::new(&include)
        .join("draco/compression/decode.h")
        .is_file()
    {
        panic!(
            "the Draco headers are not in {include}: install libdraco-dev (scripts/setup.sh does), \
             or set DRACO_INCLUDE and DRACO_LIB"
        );
    }
    cc::Build::new()
        .cpp(true)
        .std("c++17")
        .include(&include)
        .file("draco/shim.cc")
        .warnings(true)
        .compile("hlod_draco_shim");
    if let Ok(lib) = std::env::var("DRACO_LIB") {
        println!("cargo:rustc-link-search=native={lib}");
    }
    println!("cargo:rustc-link-lib=dylib=draco");
}
