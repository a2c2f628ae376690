//! Sizes in bytes as users write them: `4096`, `512K`, `64M`, `2G` (binary
//! multiples: K = 1024). The CLI's `--max-input-size` takes one.

use std::fmt;
use std::str::FromStr;

/// A size in bytes, parsed from a number with an optional `K`, `M` or `G`
/// suffix (powers of 1024; an optional trailing `B` or `iB` is accepted).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct ByteSize(pub u64);

impl FromStr for ByteSize {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let t = s.trim();
        let t = t
            .strip_suffix("iB")
            .or_else(|| t.strip_suffix('B'))
            .unwrap_or(t);
        let (digits, shift) = match t.char_indices().last() {
            Some((i, 'k' | 'K')) => (&t[..i], 10),
            Some((i, 'm' | 'M')) => (&t[..i], 20),
            Some((i, 'g' | 'G')) => (&t[..i], 30),
            _ => (t, 0),
        };
        let n: u64 = digits.trim().parse().map_err(|_| {
            format!("{s:?} is not a size: write bytes, or a number with K, M or G (e.g. 512M)")
        })?;
        n.checked_mul(1 << shift)
            .map(ByteSize)
            .ok_or_else(|| format!("{s:?} is too large"))
    }
}

impl fmt::Display for ByteSize {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.0;
        match [(30, "G"), (20, "M"), (10, "K")]
            .into_iter()
            .find(|&(s, _)| n >= 1 << s && n.is_multiple_of(1 << s))
        {
            Some((s, unit)) => write!(f, "{}{unit}", n >> s),
            None => write!(f, "{n}"),
        }
    }
}

/// A number of bytes or a string with a suffix (`max_memory: "12G"` or
/// `max_memory: 12884901888`); serialized as the number.
impl<'de> serde::Deserialize<'de> for ByteSize {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = ByteSize;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a size: bytes, or a string such as \"512M\" or \"8G\"")
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<ByteSize, E> {
                Ok(ByteSize(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<ByteSize, E> {
                u64::try_from(v)
                    .map(ByteSize)
                    .map_err(|_| E::custom(format!("{v} is not a size")))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<ByteSize, E> {
                v.parse().map_err(E::custom)
            }
        }
        d.deserialize_any(Visitor)
    }
}

impl serde::Serialize for ByteSize {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::ByteSize;

    #[test]
    fn sizes_parse_with_binary_suffixes_and_print_back() {
        for (text, bytes) in [
            ("4096", 4096),
            ("512K", 512 << 10),
            ("64m", 64 << 20),
            ("2G", 2 << 30),
            ("3GiB", 3 << 30),
            (" 10 MB ", 10 << 20),
            ("0", 0),
        ] {
            assert_eq!(text.parse::<ByteSize>(), Ok(ByteSize(bytes)), "{text}");
        }
        for bad in ["", "G", "1.5G", "-1K", "12T", "99999999999999999999G"] {
            assert!(bad.parse::<ByteSize>().is_err(), "{bad}");
        }
        assert_eq!(ByteSize(2 << 30).to_string(), "2G");
        assert_eq!(ByteSize(1536).to_string(), "1536");
        assert_eq!(ByteSize(1536 << 10).to_string(), "1536K");
    }
}
