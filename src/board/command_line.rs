//! The firmware's command line (QEMU's semihosting `arg=` words, joined by spaces): the program
//! name, then `key=value` words. Words are compared whole, so `mode=measure` does not match
//! `mode=measure-local`; a key the firmware does not know, a word without `=` or a value out of
//! range is an error that names the word, never ignored. No allocation, no panic.

/// What is wrong with a command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArgError<'a> {
    /// A word that is not `key=value` with a known key.
    Unknown(&'a [u8]),
    /// A value that is not one of the key's values (or not a number where one is expected).
    BadValue(&'a [u8]),
}

impl<'a> ArgError<'a> {
    /// The offending word, for the log.
    pub fn word(&self) -> &'a [u8] {
        match self {
            ArgError::Unknown(w) | ArgError::BadValue(w) => w,
        }
    }
}

/// A parsed command line: the words after the program name.
#[derive(Debug, Clone, Copy)]
pub struct CommandLine<'a> {
    line: &'a [u8],
}

impl<'a> CommandLine<'a> {
    /// The command line `line`; its first word is the program name and is skipped.
    pub fn new(line: &'a [u8]) -> Self {
        CommandLine { line }
    }

    /// The `key=value` words after the program name.
    fn words(&self) -> impl Iterator<Item = &'a [u8]> {
        self.line
            .split(|&c| c == b' ' || c == 0)
            .filter(|w| !w.is_empty())
            .skip(1)
    }

    /// Every word's key is among `known`, else the first word that is not.
    pub fn check(&self, known: &[&[u8]]) -> Result<(), ArgError<'a>> {
        for w in self.words() {
            match split(w) {
                Some((key, _)) if known.contains(&key) => {}
                _ => return Err(ArgError::Unknown(w)),
            }
        }
        Ok(())
    }

    /// The value of the last `key=value` word, if any.
    pub fn value(&self, key: &[u8]) -> Option<&'a [u8]> {
        self.words()
            .filter_map(split)
            .filter(|(k, _)| *k == key)
            .map(|(_, v)| v)
            .last()
    }

    /// The value of `key` as the index of one of `values` (`None` when `key` is absent).
    pub fn choice(&self, key: &[u8], values: &[&[u8]]) -> Result<Option<usize>, ArgError<'a>> {
        match self.value(key) {
            None => Ok(None),
            Some(v) => values
                .iter()
                .position(|c| *c == v)
                .map(Some)
                .ok_or(ArgError::BadValue(v)),
        }
    }

    /// The value of `key` as a decimal `u32` (`None` when `key` is absent).
    pub fn number(&self, key: &[u8]) -> Result<Option<u32>, ArgError<'a>> {
        let Some(v) = self.value(key) else {
            return Ok(None);
        };
        if v.is_empty() {
            return Err(ArgError::BadValue(v));
        }
        let mut n: u32 = 0;
        for &c in v {
            if !c.is_ascii_digit() {
                return Err(ArgError::BadValue(v));
            }
            n = n
                .checked_mul(10)
                .and_then(|n| n.checked_add((c - b'0') as u32))
                .ok_or(ArgError::BadValue(v))?;
        }
        Ok(Some(n))
    }
}

/// `key` and `value` of `key=value`.
fn split(word: &[u8]) -> Option<(&[u8], &[u8])> {
    let at = word.iter().position(|&c| c == b'=')?;
    Some((&word[..at], &word[at + 1..]))
}

#[cfg(test)]
mod tests {
    use super::*;

    const KNOWN: [&[u8]; 3] = [b"mode", b"ticks", b"feedback"];

    #[test]
    fn words_are_matched_whole() {
        let line = CommandLine::new(b"firmware-hil ticks=2000 mode=measure-local");
        assert_eq!(line.check(&KNOWN), Ok(()));
        let modes: [&[u8]; 3] = [b"track", b"measure", b"measure-local"];
        assert_eq!(line.choice(b"mode", &modes), Ok(Some(2)));
        assert_eq!(line.number(b"ticks"), Ok(Some(2000)));
        assert_eq!(line.choice(b"feedback", &[b"on", b"off"]), Ok(None));
    }

    #[test]
    fn bad_words_are_errors_naming_the_word() {
        let line = CommandLine::new(b"fw mode=measur ticks=12x warp");
        assert_eq!(
            line.check(&KNOWN),
            Err(ArgError::Unknown(b"warp".as_slice()))
        );
        assert_eq!(
            line.choice(b"mode", &[b"track", b"measure"]),
            Err(ArgError::BadValue(b"measur".as_slice()))
        );
        assert_eq!(
            line.number(b"ticks"),
            Err(ArgError::BadValue(b"12x".as_slice()))
        );
        let big = CommandLine::new(b"fw ticks=99999999999");
        assert!(big.number(b"ticks").is_err());
        assert_eq!(CommandLine::new(b"").check(&KNOWN), Ok(()));
        assert_eq!(CommandLine::new(b"fw").value(b"mode"), None);
    }
}
