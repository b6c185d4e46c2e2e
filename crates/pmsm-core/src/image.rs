//! Drive images: a designed [`crate::DriveConfig`] as 32-bit words, written where the design
//! runs (the host, with `f64` at hand) and read where the drive runs, so that a firmware that
//! knows its motor does not link the configuration's design (docs/image.md).
//!
//! Each imaged type has a fixed length in words ([`Words::WORDS`]) and a fingerprint of its
//! shape ([`Words::SCHEMA`]), both derived (`pmsm-image-derive`). Values are written and read
//! field by field, so the image does not depend on either machine's memory layout and needs
//! no `unsafe`; an image of another shape or build is refused by its schema, a short one by
//! its length, and a tag that names no variant as [`ImageError::Invalid`].

use fixed::types::extra::LeEqU32;
use fixed::{FixedI32, FixedU32};

pub(crate) use pmsm_image_derive::Words;

/// Why an image was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImageError {
    /// It does not start with [`IMAGE_MAGIC`]: not a drive image.
    Magic,
    /// It was written for a drive of another shape: another version of the library, or the
    /// same built with other features (the estimators, `ipd`, `tracking`, …). Write it again
    /// with the library and features the target uses.
    Schema {
        /// The schema this build reads.
        expected: u32,
        /// The image's.
        found: u32,
    },
    /// It is not as long as this build's image (`DriveConfig::IMAGE_WORDS` words).
    Length {
        /// Words this build reads.
        expected: u32,
        /// Words given.
        found: u32,
    },
    /// A word that is no value of its field (an enum's tag, a `bool`, a narrow integer out
    /// of its range): a corrupted image.
    Invalid,
}

impl core::fmt::Display for ImageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Magic => write!(f, "not a drive image (no magic word)"),
            Self::Schema { expected, found } => write!(
                f,
                "drive image of another library build or features (schema {found:#010x}, this \
                 build reads {expected:#010x}): write it again with the target's"
            ),
            Self::Length { expected, found } => {
                write!(
                    f,
                    "drive image of {found} words, this build reads {expected}"
                )
            }
            Self::Invalid => write!(f, "drive image corrupted (a word out of its field's range)"),
        }
    }
}

/// "PMDI", the first word of a drive image (its bytes in little-endian order).
pub const IMAGE_MAGIC: u32 = 0x4944_4D50;

/// A value as a fixed number of 32-bit words.
pub(crate) trait Words: Sized {
    /// The words of every value of the type.
    const WORDS: usize;
    /// The fingerprint of the type's shape.
    const SCHEMA: u32;
    /// The floating-point values among them (`f32`, `f64`; an enum's over all its variants):
    /// none in what the interrupt side holds.
    const FLOATS: usize = 0;
    /// Writes the value's [`Words::WORDS`] words.
    fn put(&self, out: &mut WordWriter<'_>);
    /// Reads a value written by [`Words::put`]. A word that is no value of its field marks
    /// the reader invalid ([`WordReader::invalid`]) and reads as some value of the type: the
    /// caller refuses the whole image (no branch per field on the way).
    fn get(r: &mut WordReader<'_>) -> Self;
}

/// FNV-1a's step on a word: the schema's fold.
pub(crate) const fn mix(h: u32, x: u32) -> u32 {
    (h ^ x).wrapping_mul(0x0100_0193)
}

/// FNV-1a of a name.
pub(crate) const fn hash(s: &str) -> u32 {
    let mut b = s.as_bytes();
    let mut h = 0x811C_9DC5u32;
    while let [first, rest @ ..] = b {
        h = mix(h, *first as u32);
        b = rest;
    }
    h
}

/// The larger of two lengths (const).
pub(crate) const fn max(a: usize, b: usize) -> usize {
    if a > b { a } else { b }
}

/// Where [`Words::put`] writes: a slice of exactly the image's length ([`write`] is given
/// `2 + T::WORDS` words, as many as it writes; a word past the end would be dropped).
pub(crate) struct WordWriter<'a> {
    out: &'a mut [u32],
    at: usize,
}

impl<'a> WordWriter<'a> {
    pub(crate) fn new(out: &'a mut [u32]) -> Self {
        Self { out, at: 0 }
    }

    pub(crate) fn word(&mut self, w: u32) {
        if let Some(slot) = self.out.get_mut(self.at) {
            *slot = w;
        }
        self.at += 1;
    }

    pub(crate) fn pad(&mut self, n: usize) {
        for _ in 0..n {
            self.word(0);
        }
    }
}

/// What [`Words::get`] reads from: words past the end read as 0 and mark it invalid.
pub(crate) struct WordReader<'a> {
    words: &'a [u32],
    at: usize,
    valid: bool,
}

impl<'a> WordReader<'a> {
    pub(crate) fn new(words: &'a [u32]) -> Self {
        Self {
            words,
            at: 0,
            valid: true,
        }
    }

    pub(crate) fn word(&mut self) -> u32 {
        let w = match self.words.get(self.at) {
            Some(&w) => w,
            None => {
                self.valid = false;
                0
            }
        };
        self.at += 1;
        w
    }

    /// Reads `n` words of padding, which must be 0: an image is the one of its value.
    pub(crate) fn skip(&mut self, n: usize) {
        for _ in 0..n {
            if self.word() != 0 {
                self.valid = false;
            }
        }
    }

    /// Marks the image invalid: a word that is no value of its field.
    pub(crate) fn invalid(&mut self) {
        self.valid = false;
    }

    /// Whether every word read so far was a value of its field, and all of them were read.
    fn done(&self) -> bool {
        self.valid && self.at == self.words.len()
    }
}

/// Types of one word whose every bit pattern is a value.
macro_rules! word_types {
    ($($t:ty => $name:literal),* $(,)?) => {$(
        impl Words for $t {
            const WORDS: usize = 1;
            const SCHEMA: u32 = hash($name);
            fn put(&self, out: &mut WordWriter<'_>) {
                out.word(*self as u32);
            }
            fn get(r: &mut WordReader<'_>) -> Self {
                r.word() as $t
            }
        }
    )*};
}
word_types!(u32 => "u32", i32 => "i32");

/// Narrow integers: one word, refused out of their range.
macro_rules! narrow_types {
    ($($t:ty => $name:literal),* $(,)?) => {$(
        impl Words for $t {
            const WORDS: usize = 1;
            const SCHEMA: u32 = hash($name);
            fn put(&self, out: &mut WordWriter<'_>) {
                out.word(i64::from(*self) as u32);
            }
            fn get(r: &mut WordReader<'_>) -> Self {
                // Sign-extended for the signed types, zero-extended for the others.
                let w = r.word();
                let v = w as $t;
                if i64::from(v) as u32 != w {
                    r.invalid();
                }
                v
            }
        }
    )*};
}
narrow_types!(u8 => "u8", u16 => "u16", i8 => "i8", i16 => "i16");

impl Words for bool {
    const WORDS: usize = 1;
    const SCHEMA: u32 = hash("bool");
    fn put(&self, out: &mut WordWriter<'_>) {
        out.word(u32::from(*self));
    }
    fn get(r: &mut WordReader<'_>) -> Self {
        let w = r.word();
        if w > 1 {
            r.invalid();
        }
        w == 1
    }
}

/// Two words, low first.
macro_rules! double_types {
    ($($t:ty => $name:literal, $floats:literal, $to:expr, $from:expr);* $(;)?) => {$(
        impl Words for $t {
            const WORDS: usize = 2;
            const SCHEMA: u32 = hash($name);
            const FLOATS: usize = $floats;
            fn put(&self, out: &mut WordWriter<'_>) {
                let b: u64 = $to(*self);
                out.word(b as u32);
                out.word((b >> 32) as u32);
            }
            fn get(r: &mut WordReader<'_>) -> Self {
                let lo = u64::from(r.word());
                let hi = u64::from(r.word());
                $from(lo | hi << 32)
            }
        }
    )*};
}
double_types!(
    u64 => "u64", 0, |v: u64| v, |b: u64| b;
    i64 => "i64", 0, |v: i64| v as u64, |b: u64| b as i64;
    f64 => "f64", 1, f64::to_bits, f64::from_bits;
);

impl Words for f32 {
    const WORDS: usize = 1;
    const SCHEMA: u32 = hash("f32");
    const FLOATS: usize = 1;
    fn put(&self, out: &mut WordWriter<'_>) {
        out.word(self.to_bits());
    }
    fn get(r: &mut WordReader<'_>) -> Self {
        f32::from_bits(r.word())
    }
}

/// Fixed-point numbers: their bits, the format in the schema.
macro_rules! fixed_types {
    ($($t:ident, $bound:ident, $bits:ty, $name:literal);* $(;)?) => {$(
        impl<F: $bound> Words for $t<F> {
            const WORDS: usize = <$bits as Words>::WORDS;
            const SCHEMA: u32 = mix(hash($name), F::U32);
            fn put(&self, out: &mut WordWriter<'_>) {
                self.to_bits().put(out);
            }
            fn get(r: &mut WordReader<'_>) -> Self {
                Self::from_bits(<$bits>::get(r))
            }
        }
    )*};
}
fixed_types!(
    FixedI32, LeEqU32, i32, "FixedI32";
    FixedU32, LeEqU32, u32, "FixedU32";
);

impl<T: Words> Words for Option<T> {
    const WORDS: usize = 1 + T::WORDS;
    const SCHEMA: u32 = mix(hash("Option"), T::SCHEMA);
    const FLOATS: usize = T::FLOATS;
    fn put(&self, out: &mut WordWriter<'_>) {
        match self {
            None => {
                out.word(0);
                out.pad(T::WORDS);
            }
            Some(v) => {
                out.word(1);
                v.put(out);
            }
        }
    }
    fn get(r: &mut WordReader<'_>) -> Self {
        match r.word() {
            1 => Some(T::get(r)),
            tag => {
                if tag != 0 {
                    r.invalid();
                }
                r.skip(T::WORDS);
                None
            }
        }
    }
}

impl<T: Words + Copy + Default, const N: usize> Words for [T; N] {
    const WORDS: usize = N * T::WORDS;
    const SCHEMA: u32 = mix(mix(hash("array"), N as u32), T::SCHEMA);
    const FLOATS: usize = N * T::FLOATS;
    fn put(&self, out: &mut WordWriter<'_>) {
        for v in self {
            v.put(out);
        }
    }
    fn get(r: &mut WordReader<'_>) -> Self {
        let mut a = [T::default(); N];
        for v in &mut a {
            *v = T::get(r);
        }
        a
    }
}

impl<A: Words, B: Words> Words for (A, B) {
    const WORDS: usize = A::WORDS + B::WORDS;
    const SCHEMA: u32 = mix(mix(hash("pair"), A::SCHEMA), B::SCHEMA);
    const FLOATS: usize = A::FLOATS + B::FLOATS;
    fn put(&self, out: &mut WordWriter<'_>) {
        self.0.put(out);
        self.1.put(out);
    }
    fn get(r: &mut WordReader<'_>) -> Self {
        (A::get(r), B::get(r))
    }
}

/// Writes `value`'s image (magic, schema, its words) into `out`, which holds exactly
/// `2 + T::WORDS` words.
pub(crate) fn write<T: Words>(value: &T, out: &mut [u32]) {
    let mut w = WordWriter::new(out);
    w.word(IMAGE_MAGIC);
    w.word(T::SCHEMA);
    value.put(&mut w);
}

/// Reads an image written by [`write`].
pub(crate) fn read<T: Words>(words: &[u32]) -> Result<T, ImageError> {
    let expected = 2 + T::WORDS;
    if words.first() != Some(&IMAGE_MAGIC) {
        return Err(ImageError::Magic);
    }
    let found = words.get(1).copied().unwrap_or(0);
    if found != T::SCHEMA {
        return Err(ImageError::Schema {
            expected: T::SCHEMA,
            found,
        });
    }
    if words.len() != expected {
        return Err(ImageError::Length {
            expected: expected as u32,
            found: words.len() as u32,
        });
    }
    let mut r = WordReader::new(words.get(2..).unwrap_or(&[]));
    let value = T::get(&mut r);
    if r.done() {
        Ok(value)
    } else {
        Err(ImageError::Invalid)
    }
}

impl crate::DriveConfig {
    /// Words of a drive image of this build (its schema and length depend on the library's
    /// version and features, not on the motor).
    pub const IMAGE_WORDS: usize = 2 + <Self as Words>::WORDS;

    /// The schema of this build's drive images, their second word: a firmware that embeds an
    /// image can check it at compile time.
    pub const IMAGE_SCHEMA: u32 = <Self as Words>::SCHEMA;

    /// Writes the drive's image, to be read back by [`crate::DriveConfig::from_image`] on a
    /// target built from the same library with the same features: magic, schema, then every
    /// coefficient and setting of the configuration (the design's `f64` figures as their
    /// bits), docs/image.md.
    pub fn write_image(&self, out: &mut [u32; Self::IMAGE_WORDS]) {
        write(self, out);
    }

    /// The configuration an image holds, without designing it: no `f64` arithmetic, so a
    /// firmware that builds its drive this way links none of the configuration's design
    /// (only the short design of the task's learners, which [`crate::DriveTask::new`] runs from
    /// the configuration's motor). Refuses an image of another build or shape
    /// ([`ImageError`]).
    pub fn from_image(words: &[u32]) -> Result<Self, ImageError> {
        read(words)
    }
}

#[cfg(test)]
mod tests;
