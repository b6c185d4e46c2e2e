//! The recording the host writes and the firmware replays: for each case, the input and
//! output words of every step.
//!
//! Layout, all integers little-endian:
//!
//! ```text
//! magic    8 bytes  b"PILREC01"
//! cases    u32
//! then per case:
//!   name     16 bytes, ASCII, zero-padded
//!   inputs   u32      input words per step
//!   outputs  u32      output words per step
//!   steps    u32
//!   words    steps × (inputs + outputs) i32: inputs of step 0, outputs of step 0, inputs of step 1, …
//! ```
//!
//! Words are the raw bits of the fixed-point values (`Pu::to_bits`, `Angle.0`, …), so a
//! comparison of words is a bit-for-bit comparison.

/// First bytes of a recording (the last two digits are the format version).
pub const MAGIC: [u8; 8] = *b"PILREC01";
/// Bytes of a case name.
pub const NAME_LEN: usize = 16;
/// Bytes of the file header.
pub const FILE_HEADER_LEN: usize = 12;
/// Bytes of a case header.
pub const CASE_HEADER_LEN: usize = NAME_LEN + 12;

/// What is wrong with a recording.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormatError {
    /// The magic is not [`MAGIC`] (not a recording, or another version).
    Magic,
    /// The data ends before the headers say.
    Truncated,
    /// Bytes follow the last case.
    Trailing,
    /// A name is longer than [`NAME_LEN`] or not ASCII.
    Name,
    /// A size does not fit.
    Size,
}

impl core::fmt::Display for FormatError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Magic => "not a PIL recording (bad magic or version)",
            Self::Truncated => "recording truncated",
            Self::Trailing => "bytes after the last case",
            Self::Name => "case name longer than 16 bytes or not ASCII",
            Self::Size => "case too large",
        })
    }
}

fn u32_at(bytes: &[u8], at: usize) -> Result<u32, FormatError> {
    match bytes.get(at..at + 4) {
        Some(&[a, b, c, d]) => Ok(u32::from_le_bytes([a, b, c, d])),
        _ => Err(FormatError::Truncated),
    }
}

/// The file header for `cases` cases.
pub fn file_header(cases: u32) -> [u8; FILE_HEADER_LEN] {
    let mut h = [0u8; FILE_HEADER_LEN];
    h[..8].copy_from_slice(&MAGIC);
    h[8..].copy_from_slice(&cases.to_le_bytes());
    h
}

/// The header of one case; its `steps × (inputs + outputs)` words follow it.
pub fn case_header(
    name: &str,
    inputs: usize,
    outputs: usize,
    steps: usize,
) -> Result<[u8; CASE_HEADER_LEN], FormatError> {
    if name.len() > NAME_LEN || !name.is_ascii() || name.as_bytes().contains(&0) {
        return Err(FormatError::Name);
    }
    let size = |x: usize| u32::try_from(x).map_err(|_| FormatError::Size);
    let mut h = [0u8; CASE_HEADER_LEN];
    h[..name.len()].copy_from_slice(name.as_bytes());
    h[NAME_LEN..NAME_LEN + 4].copy_from_slice(&size(inputs)?.to_le_bytes());
    h[NAME_LEN + 4..NAME_LEN + 8].copy_from_slice(&size(outputs)?.to_le_bytes());
    h[NAME_LEN + 8..].copy_from_slice(&size(steps)?.to_le_bytes());
    Ok(h)
}

/// A parsed recording (borrowing the bytes).
#[derive(Clone, Copy, Debug)]
pub struct Recording<'a> {
    cases: u32,
    body: &'a [u8],
}

impl<'a> Recording<'a> {
    /// Checks the file header and every case header.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, FormatError> {
        if bytes.get(..8) != Some(&MAGIC[..]) {
            return Err(FormatError::Magic);
        }
        let cases = u32_at(bytes, 8)?;
        let rec = Self {
            cases,
            body: bytes.get(FILE_HEADER_LEN..).unwrap_or(&[]),
        };
        let mut rest = rec.body;
        for _ in 0..cases {
            let (_, tail) = CaseData::split(rest)?;
            rest = tail;
        }
        if !rest.is_empty() {
            return Err(FormatError::Trailing);
        }
        Ok(rec)
    }

    /// Number of cases.
    pub fn len(&self) -> usize {
        self.cases as usize
    }

    /// True if there are no cases.
    pub fn is_empty(&self) -> bool {
        self.cases == 0
    }

    /// The cases, in file order.
    pub fn cases(&self) -> impl Iterator<Item = CaseData<'a>> + 'a {
        let mut rest = self.body;
        (0..self.cases).map_while(move |_| {
            let (case, tail) = CaseData::split(rest).ok()?;
            rest = tail;
            Some(case)
        })
    }
}

/// The recorded steps of one case.
#[derive(Clone, Copy, Debug)]
pub struct CaseData<'a> {
    /// Case name (see [`crate::cases`]).
    pub name: &'a str,
    /// Input words per step.
    pub inputs: usize,
    /// Output words per step.
    pub outputs: usize,
    /// Steps recorded.
    pub steps: usize,
    words: &'a [u8],
}

impl<'a> CaseData<'a> {
    fn split(bytes: &'a [u8]) -> Result<(Self, &'a [u8]), FormatError> {
        let name = bytes.get(..NAME_LEN).ok_or(FormatError::Truncated)?;
        let end = name.iter().position(|&b| b == 0).unwrap_or(NAME_LEN);
        let name = core::str::from_utf8(&name[..end]).map_err(|_| FormatError::Name)?;
        let inputs = u32_at(bytes, NAME_LEN)? as usize;
        let outputs = u32_at(bytes, NAME_LEN + 4)? as usize;
        let steps = u32_at(bytes, NAME_LEN + 8)? as usize;
        let len = steps
            .checked_mul(inputs + outputs)
            .and_then(|w| w.checked_mul(4))
            .ok_or(FormatError::Size)?;
        let words = bytes
            .get(CASE_HEADER_LEN..CASE_HEADER_LEN + len)
            .ok_or(FormatError::Truncated)?;
        let case = Self {
            name,
            inputs,
            outputs,
            steps,
            words,
        };
        Ok((case, &bytes[CASE_HEADER_LEN + len..]))
    }

    fn word(&self, index: usize) -> i32 {
        match self.words.get(4 * index..4 * index + 4) {
            Some(&[a, b, c, d]) => i32::from_le_bytes([a, b, c, d]),
            _ => 0,
        }
    }

    /// Copies the inputs of `step` into `out` (as many as fit).
    pub fn inputs_of(&self, step: usize, out: &mut [i32]) {
        let first = step * (self.inputs + self.outputs);
        for (j, w) in out.iter_mut().take(self.inputs).enumerate() {
            *w = self.word(first + j);
        }
    }

    /// Output `j` of `step`, as recorded.
    pub fn output(&self, step: usize, j: usize) -> i32 {
        self.word(step * (self.inputs + self.outputs) + self.inputs + j)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    fn recording(cases: &[(&str, usize, usize, &[i32])]) -> Vec<u8> {
        let mut b = file_header(cases.len() as u32).to_vec();
        for (name, i, o, words) in cases {
            let steps = words.len() / (i + o);
            b.extend_from_slice(&case_header(name, *i, *o, steps).unwrap());
            b.extend(words.iter().flat_map(|w| w.to_le_bytes()));
        }
        b
    }

    #[test]
    fn round_trip() {
        let a = [1, -2, 3, i32::MIN, i32::MAX, 6];
        let b = [7, 8, 9];
        let bytes = recording(&[("first", 2, 1, &a), ("second-case-16by", 0, 3, &b)]);
        let rec = Recording::parse(&bytes).unwrap();
        assert_eq!(rec.len(), 2);
        let cases: Vec<_> = rec.cases().collect();
        assert_eq!(
            (
                cases[0].name,
                cases[0].inputs,
                cases[0].outputs,
                cases[0].steps
            ),
            ("first", 2, 1, 2)
        );
        let mut input = [0; 2];
        cases[0].inputs_of(1, &mut input);
        assert_eq!(input, [i32::MIN, i32::MAX]);
        assert_eq!(cases[0].output(0, 0), 3);
        assert_eq!(cases[0].output(1, 0), 6);
        assert_eq!(cases[1].name, "second-case-16by");
        assert_eq!(
            (0..3).map(|j| cases[1].output(0, j)).collect::<Vec<_>>(),
            [7, 8, 9]
        );
    }

    #[test]
    fn rejects_bad_recordings() {
        let bytes = recording(&[("x", 1, 1, &[1, 2, 3, 4])]);
        assert_eq!(
            Recording::parse(&bytes[..5]).err(),
            Some(FormatError::Magic)
        );
        assert_eq!(
            Recording::parse(&bytes[..bytes.len() - 1]).err(),
            Some(FormatError::Truncated)
        );
        let mut long = bytes.clone();
        long.push(0);
        assert_eq!(Recording::parse(&long).err(), Some(FormatError::Trailing));
        let mut other = bytes;
        other[7] = b'2';
        assert_eq!(Recording::parse(&other).err(), Some(FormatError::Magic));
        assert_eq!(
            case_header("seventeen-bytes-x", 1, 1, 1).err(),
            Some(FormatError::Name)
        );
    }
}
