//! The checked-in header is what cbindgen generates from this crate now.
//! `UPDATE_HEADER=1 cargo test -p shadowcull-bindings --test main header` rewrites it.

#[test]
fn checked_in_header_is_current() {
    let dir = env!("CARGO_MANIFEST_DIR");
    let config =
        cbindgen::Config::from_file(format!("{dir}/cbindgen.toml")).expect("cbindgen.toml");
    let bindings = cbindgen::Builder::new()
        .with_crate(dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header");
    let mut fresh = Vec::new();
    bindings.write(&mut fresh);
    let path = format!("{dir}/include/shadowcull.h");
    if std::env::var_os("UPDATE_HEADER").is_some() {
        std::fs::write(&path, &fresh).expect("write the header");
        return;
    }
    let checked_in = std::fs::read(&path).unwrap_or_default();
    assert!(
        checked_in == fresh,
        "{path} differs from a fresh generation: run \
         `UPDATE_HEADER=1 cargo test -p shadowcull-bindings --test main header` and commit it"
    );
}
