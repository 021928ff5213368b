//! Decoding the firmware's defmt stream with the `defmt-decoder` library.

use anyhow::{anyhow, Context, Result};
use defmt_decoder::{DecodeError, Frame, Locations, StreamDecoder, Table};
use std::path::Path;

use crate::cmd::workspace_root;

/// The defmt table and source locations of one ELF.
pub struct LogFormat {
    table: Table,
    locations: Option<Locations>,
}

impl LogFormat {
    /// Reads the defmt table (and, when present, the file:line table) out of `elf`.
    pub fn from_elf(elf: &Path) -> Result<Self> {
        let bytes = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
        let table = Table::parse(&bytes)
            .with_context(|| format!("parsing the defmt table of {}", elf.display()))?
            .ok_or_else(|| anyhow!("{} has no defmt data (.defmt section)", elf.display()))?;
        let locations = table.get_locations(&bytes).ok().filter(|l| !l.is_empty());
        Ok(Self { table, locations })
    }

    /// A decoder for one byte stream.
    pub fn decoder(&self) -> LogDecoder<'_> {
        LogDecoder {
            format: self,
            stream: self.table.new_stream_decoder(),
            malformed: 0,
        }
    }

    fn render(&self, frame: &Frame<'_>) -> String {
        let timestamp = frame
            .display_timestamp()
            .map(|t| t.to_string())
            .unwrap_or_default();
        let level = frame
            .level()
            .map(|l| l.as_str().to_uppercase())
            .unwrap_or_else(|| "PRINT".into());
        let mut line = format!("{timestamp:>10} {level:<5} {}", frame.display_message());
        if let Some(loc) = self.locations.as_ref().and_then(|l| l.get(&frame.index())) {
            let file = loc.file.strip_prefix(workspace_root()).unwrap_or(&loc.file);
            line.push_str(&format!("  ({}:{})", file.display(), loc.line));
        }
        line
    }
}

/// Turns received bytes into rendered log lines.
pub struct LogDecoder<'a> {
    format: &'a LogFormat,
    stream: Box<dyn StreamDecoder + Send + Sync + 'a>,
    malformed: usize,
}

impl LogDecoder<'_> {
    /// Feeds `bytes` and returns every line they complete.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<String> {
        self.stream.received(bytes);
        let mut lines = Vec::new();
        loop {
            match self.stream.decode() {
                Ok(frame) => lines.push(self.format.render(&frame)),
                Err(DecodeError::UnexpectedEof) => break,
                Err(DecodeError::Malformed) => {
                    // rzcobs frames resynchronise at the next frame boundary.
                    self.malformed += 1;
                    lines.push("(xtask: a malformed defmt frame was skipped)".into());
                    if !self.format.table.encoding().can_recover() {
                        break;
                    }
                }
            }
        }
        lines
    }

    /// Frames that could not be decoded so far.
    pub fn malformed(&self) -> usize {
        self.malformed
    }
}
