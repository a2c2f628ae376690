//! Command-line parsing shared by the examples (`raster_bench`,
//! `shadow_bench`, `host_loop`): spelling tables for enum-like options, and
//! the `WxH` resolution.

use clap::builder::{PossibleValuesParser, TypedValueParser};

/// A clap value parser that accepts exactly the spellings of `table` and
/// yields their values; `--help` lists the spellings.
pub fn one_of<T: Copy + Send + Sync + 'static>(
    table: &'static [(&'static str, T)],
) -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(table.iter().map(|(n, _)| *n)).map(move |v| {
        table
            .iter()
            .find(|(n, _)| *n == v)
            .expect("PossibleValuesParser only passes listed spellings")
            .1
    })
}

/// The spelling of `value` in `table`.
///
/// # Panics
/// When `value` has no spelling in `table` (a table missing a variant).
pub fn name_of<T: PartialEq>(table: &[(&'static str, T)], value: &T) -> &'static str {
    table
        .iter()
        .find(|(_, t)| t == value)
        .map(|(n, _)| *n)
        .expect("every value has a spelling")
}

/// A resolution `WxH`, e.g. `1280x1024`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("{s:?}: a resolution looks like 1280x1024"))?;
    Ok((
        w.parse().map_err(|e| format!("width {w:?}: {e}"))?,
        h.parse().map_err(|e| format!("height {h:?}: {e}"))?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    const SIDES: &[(&str, u8)] = &[("left", 1), ("right", 2)];

    #[derive(Parser, Debug)]
    struct Args {
        #[arg(long, value_parser = one_of(SIDES))]
        side: u8,
        #[arg(long, value_parser = parse_size)]
        size: (u32, u32),
    }

    #[test]
    fn spellings_parse_to_values_and_back() {
        let a = Args::try_parse_from(["t", "--side", "right", "--size", "640x480"]).unwrap();
        assert_eq!((a.side, a.size), (2, (640, 480)));
        assert_eq!(name_of(SIDES, &a.side), "right");
        let err = Args::try_parse_from(["t", "--side", "up", "--size", "1x1"]).unwrap_err();
        assert!(err.to_string().contains("left"), "{err}");
    }

    #[test]
    fn bad_sizes_name_the_part() {
        assert!(parse_size("640").unwrap_err().contains("1280x1024"));
        assert!(parse_size("ax2").unwrap_err().starts_with("width \"a\""));
        assert!(parse_size("2x-1").unwrap_err().starts_with("height \"-1\""));
    }
}
