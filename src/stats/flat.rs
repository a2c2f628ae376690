//! The one flattening of the statistics structs.
//!
//! A statistics value serializes (serde) as a tree of structs whose leaves
//! are counters, times and, in `compare.csv`, names. [`leaves`] lists them
//! in declaration order with their dotted paths
//! (`shadow.stencil.pixels_processed`), [`cells`] lists their values alone,
//! and [`from_cells`] builds the value back from such a list (a derived
//! `Deserialize` reads a struct's fields in declaration order). The CSV
//! rows, the per-row tracing event, the totals and `compare`'s table are
//! computed through these, so a field added to a statistics struct reaches
//! each of them without being listed again.

use serde::de::{self, DeserializeOwned, DeserializeSeed, SeqAccess, Visitor};
use serde::ser::{self, Impossible, SerializeMap, SerializeStruct};
use serde::Serialize;
use std::fmt;

/// One leaf of a flattened statistics value.
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    /// A counter: any unsigned integer field.
    Count(u64),
    /// A time in milliseconds: any floating-point field.
    Ms(f64),
    /// A name (`compare.csv`'s variant and option columns).
    Text(String),
}

impl Cell {
    /// The cell as CSV text: counters in decimal, times with three
    /// decimals, names as they are (the CSV writer quotes them if needed).
    pub fn text(&self) -> String {
        match self {
            Cell::Count(n) => n.to_string(),
            Cell::Ms(ms) => format!("{ms:.3}"),
            Cell::Text(s) => s.clone(),
        }
    }

    /// `text` read as a cell of the same kind as `self` (`None` when it is
    /// not one).
    pub fn parse_like(&self, text: &str) -> Option<Cell> {
        Some(match self {
            Cell::Count(_) => Cell::Count(text.parse().ok()?),
            Cell::Ms(_) => Cell::Ms(text.parse().ok()?),
            Cell::Text(_) => Cell::Text(text.to_string()),
        })
    }

    /// The counter, or 0 for another kind.
    pub fn count(&self) -> u64 {
        match self {
            Cell::Count(n) => *n,
            _ => 0,
        }
    }

    /// The time, or 0 for another kind.
    pub fn ms(&self) -> f64 {
        match self {
            Cell::Ms(ms) => *ms,
            _ => 0.0,
        }
    }

    /// Counters and times added; a name stays as it is.
    fn plus(self, other: &Cell) -> Cell {
        match (self, other) {
            (Cell::Count(a), Cell::Count(b)) => Cell::Count(a + b),
            (Cell::Ms(a), Cell::Ms(b)) => Cell::Ms(a + b),
            (a, _) => a,
        }
    }
}

impl Serialize for Cell {
    fn serialize<S: ser::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Cell::Count(n) => s.serialize_u64(*n),
            Cell::Ms(ms) => s.serialize_f64(*ms),
            Cell::Text(t) => s.serialize_str(t),
        }
    }
}

/// Named cells in column order; serializes as a map (`{"eye_ms": 1.5, …}`),
/// the shape `summary.json`'s totals and the Python dicts have.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Columns(pub Vec<(&'static str, Cell)>);

impl Columns {
    /// The cell of column `name`.
    pub fn get(&self, name: &str) -> Option<&Cell> {
        self.0.iter().find(|(n, _)| *n == name).map(|(_, c)| c)
    }

    /// The columns in order.
    pub fn iter(&self) -> impl Iterator<Item = &(&'static str, Cell)> {
        self.0.iter()
    }
}

impl Serialize for Columns {
    fn serialize<S: ser::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(self.0.len()))?;
        for (name, cell) in &self.0 {
            map.serialize_entry(name, cell)?;
        }
        map.end()
    }
}

/// The leaves of `value`: each one's dotted path and cell, in order.
///
/// # Panics
/// For a value with other leaves than unsigned integers, floats and
/// strings, or other containers than structs (no statistics struct has any).
pub(crate) fn leaves<T: Serialize>(value: &T) -> Vec<(String, Cell)> {
    let mut names = Vec::new();
    let cells = flatten(value, Some(&mut names));
    names.into_iter().zip(cells).collect()
}

/// The cells of `value`'s leaves, in order ([`leaves`] without the paths).
///
/// # Panics
/// As [`leaves`].
pub(crate) fn cells<T: Serialize>(value: &T) -> Vec<Cell> {
    flatten(value, None)
}

fn flatten<T: Serialize>(value: &T, names: Option<&mut Vec<String>>) -> Vec<Cell> {
    let mut f = Flatten {
        path: Vec::new(),
        names,
        cells: Vec::new(),
    };
    if let Err(e) = value.serialize(&mut f) {
        panic!("not a statistics value: {e}");
    }
    f.cells
}

/// The value whose leaves are `cells`, in order (the inverse of [`cells`]).
///
/// # Errors
/// Fewer or more cells than `T` has leaves, or a cell of another kind than
/// its leaf (a time for a counter, a counter out of the field's range).
pub(crate) fn from_cells<T: DeserializeOwned>(
    cells: impl IntoIterator<Item = Cell>,
) -> Result<T, FlatError> {
    let mut de = Unflatten {
        cells: cells.into_iter(),
    };
    let value = T::deserialize(&mut de)?;
    match de.cells.next() {
        Some(_) => Err(FlatError("more cells than the value has leaves".into())),
        None => Ok(value),
    }
}

/// Adds `b`'s counters and times to `a`'s, leaf by leaf.
pub(crate) fn add<T: Serialize + DeserializeOwned>(a: &mut T, b: &T) {
    let b = cells(b);
    let sum = cells(a).into_iter().zip(&b).map(|(x, y)| x.plus(y));
    *a = from_cells(sum).expect("the sum has the leaves of its terms");
}

/// Why a value could not be flattened or built back.
#[derive(Debug)]
pub struct FlatError(String);

impl fmt::Display for FlatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for FlatError {}

impl ser::Error for FlatError {
    fn custom<M: fmt::Display>(msg: M) -> Self {
        FlatError(msg.to_string())
    }
}

impl de::Error for FlatError {
    fn custom<M: fmt::Display>(msg: M) -> Self {
        FlatError(msg.to_string())
    }
}

/// The serializer behind [`leaves`] and [`cells`].
struct Flatten<'a> {
    path: Vec<&'static str>,
    names: Option<&'a mut Vec<String>>,
    cells: Vec<Cell>,
}

impl Flatten<'_> {
    fn leaf(&mut self, cell: Cell) -> Result<(), FlatError> {
        if let Some(names) = &mut self.names {
            names.push(self.path.join("."));
        }
        self.cells.push(cell);
        Ok(())
    }

    fn unsupported(&self, what: &str) -> FlatError {
        FlatError(format!("`{}` is {what}", self.path.join(".")))
    }
}

impl ser::Serializer for &mut Flatten<'_> {
    type Ok = ();
    type Error = FlatError;
    type SerializeSeq = Impossible<(), FlatError>;
    type SerializeTuple = Impossible<(), FlatError>;
    type SerializeTupleStruct = Impossible<(), FlatError>;
    type SerializeTupleVariant = Impossible<(), FlatError>;
    type SerializeMap = Impossible<(), FlatError>;
    type SerializeStruct = Self;
    type SerializeStructVariant = Impossible<(), FlatError>;

    fn serialize_u8(self, v: u8) -> Result<(), FlatError> {
        self.leaf(Cell::Count(v.into()))
    }
    fn serialize_u16(self, v: u16) -> Result<(), FlatError> {
        self.leaf(Cell::Count(v.into()))
    }
    fn serialize_u32(self, v: u32) -> Result<(), FlatError> {
        self.leaf(Cell::Count(v.into()))
    }
    fn serialize_u64(self, v: u64) -> Result<(), FlatError> {
        self.leaf(Cell::Count(v))
    }
    fn serialize_f32(self, v: f32) -> Result<(), FlatError> {
        self.leaf(Cell::Ms(v.into()))
    }
    fn serialize_f64(self, v: f64) -> Result<(), FlatError> {
        self.leaf(Cell::Ms(v))
    }
    fn serialize_str(self, v: &str) -> Result<(), FlatError> {
        self.leaf(Cell::Text(v.to_string()))
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Self, FlatError> {
        Ok(self)
    }

    fn serialize_bool(self, _: bool) -> Result<(), FlatError> {
        Err(self.unsupported("a bool"))
    }
    fn serialize_i8(self, _: i8) -> Result<(), FlatError> {
        Err(self.unsupported("signed"))
    }
    fn serialize_i16(self, _: i16) -> Result<(), FlatError> {
        Err(self.unsupported("signed"))
    }
    fn serialize_i32(self, _: i32) -> Result<(), FlatError> {
        Err(self.unsupported("signed"))
    }
    fn serialize_i64(self, _: i64) -> Result<(), FlatError> {
        Err(self.unsupported("signed"))
    }
    fn serialize_char(self, _: char) -> Result<(), FlatError> {
        Err(self.unsupported("a char"))
    }
    fn serialize_bytes(self, _: &[u8]) -> Result<(), FlatError> {
        Err(self.unsupported("bytes"))
    }
    fn serialize_none(self) -> Result<(), FlatError> {
        Err(self.unsupported("an option"))
    }
    fn serialize_some<T: Serialize + ?Sized>(self, _: &T) -> Result<(), FlatError> {
        Err(self.unsupported("an option"))
    }
    fn serialize_unit(self) -> Result<(), FlatError> {
        Err(self.unsupported("a unit"))
    }
    fn serialize_unit_struct(self, _: &'static str) -> Result<(), FlatError> {
        Err(self.unsupported("a unit struct"))
    }
    fn serialize_unit_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
    ) -> Result<(), FlatError> {
        Err(self.unsupported("an enum"))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: &T,
    ) -> Result<(), FlatError> {
        Err(self.unsupported("a newtype"))
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: &T,
    ) -> Result<(), FlatError> {
        Err(self.unsupported("an enum"))
    }
    fn serialize_seq(self, _: Option<usize>) -> Result<Self::SerializeSeq, FlatError> {
        Err(self.unsupported("a sequence"))
    }
    fn serialize_tuple(self, _: usize) -> Result<Self::SerializeTuple, FlatError> {
        Err(self.unsupported("a tuple"))
    }
    fn serialize_tuple_struct(
        self,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleStruct, FlatError> {
        Err(self.unsupported("a tuple"))
    }
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleVariant, FlatError> {
        Err(self.unsupported("an enum"))
    }
    fn serialize_map(self, _: Option<usize>) -> Result<Self::SerializeMap, FlatError> {
        Err(self.unsupported("a map"))
    }
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStructVariant, FlatError> {
        Err(self.unsupported("an enum"))
    }
}

impl SerializeStruct for &mut Flatten<'_> {
    type Ok = ();
    type Error = FlatError;

    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), FlatError> {
        self.path.push(key);
        value.serialize(&mut **self)?;
        self.path.pop();
        Ok(())
    }

    fn end(self) -> Result<(), FlatError> {
        Ok(())
    }
}

/// The deserializer behind [`from_cells`]: every struct reads its fields as
/// a sequence, every leaf takes the next cell.
struct Unflatten<I> {
    cells: I,
}

impl<'de, I: Iterator<Item = Cell>> de::Deserializer<'de> for &mut Unflatten<I> {
    type Error = FlatError;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, FlatError> {
        match self.cells.next() {
            Some(Cell::Count(n)) => visitor.visit_u64(n),
            Some(Cell::Ms(ms)) => visitor.visit_f64(ms),
            Some(Cell::Text(s)) => visitor.visit_string(s),
            None => Err(FlatError("fewer cells than the value has leaves".into())),
        }
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, FlatError> {
        visitor.visit_seq(Fields {
            de: self,
            left: fields.len(),
        })
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf option unit unit_struct newtype_struct seq tuple
        tuple_struct map enum identifier ignored_any
    }
}

/// A struct's fields, read in order.
struct Fields<'a, I> {
    de: &'a mut Unflatten<I>,
    left: usize,
}

impl<'de, I: Iterator<Item = Cell>> SeqAccess<'de> for Fields<'_, I> {
    type Error = FlatError;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, FlatError> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        seed.deserialize(&mut *self.de).map(Some)
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.left)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::{Deserialize, Serialize};

    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    struct Inner {
        n: usize,
        t: f64,
    }

    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    struct Outer {
        name: String,
        a: u32,
        inner: Inner,
        b: u64,
    }

    #[test]
    fn leaves_are_paths_in_order_and_come_back() {
        let v = Outer {
            name: "x,y".into(),
            a: 3,
            inner: Inner { n: 7, t: 1.25 },
            b: 9,
        };
        let l = leaves(&v);
        let paths: Vec<&str> = l.iter().map(|(p, _)| p.as_str()).collect();
        assert_eq!(paths, ["name", "a", "inner.n", "inner.t", "b"]);
        assert_eq!(l[3].1, Cell::Ms(1.25));
        let back: Outer = from_cells(cells(&v)).unwrap();
        assert_eq!(back, v);
        let mut sum = v.clone();
        add(&mut sum, &v);
        assert_eq!((sum.a, sum.inner.n, sum.inner.t, sum.b), (6, 14, 2.5, 18));
        assert_eq!(sum.name, "x,y");
    }

    #[test]
    fn wrong_cells_are_errors() {
        let mut c = cells(&Outer::default());
        c.pop();
        assert!(from_cells::<Outer>(c.clone()).is_err());
        c.push(Cell::Ms(1.0));
        assert!(
            from_cells::<Outer>(c.clone()).is_err(),
            "a time for a counter"
        );
        c.pop();
        c.push(Cell::Count(1));
        c.push(Cell::Count(1));
        assert!(from_cells::<Outer>(c).is_err(), "one cell too many");
        let mut c = cells(&Outer::default());
        c[1] = Cell::Count(u64::from(u32::MAX) + 1);
        assert!(from_cells::<Outer>(c).is_err(), "out of a u32's range");
    }

    #[test]
    fn cells_read_and_write_as_csv_text() {
        assert_eq!(Cell::Ms(1.23456).text(), "1.235");
        assert_eq!(Cell::Count(42).text(), "42");
        assert_eq!(Cell::Ms(0.0).parse_like("2.5"), Some(Cell::Ms(2.5)));
        assert_eq!(Cell::Count(0).parse_like("2.5"), None);
        assert_eq!(Cell::Count(0).parse_like("x"), None);
    }
}
