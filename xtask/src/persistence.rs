//! The settings store on an emulated board, end to end: the board serves the protocol
//! with its flash in a host file (`--flash`), so a power cycle is two runs with one file.
//!
//! 1. Save and power cycle: a configuration saved (after a save while enabled was refused)
//!    is back after the next boot, as `vsa status` shows it.
//! 2. Power cuts: the board loses power after word write N of a save, for every N of the
//!    save (`--flash-cut-after`; the firmware exits at once, the file keeping the words
//!    written), then boots again from that file: it must come up with the complete old or
//!    the complete new configuration — never a mix, a rejected record or no answer. The
//!    same for every word write of a factory reset.
//! 3. Wear: 1 000 saves in a row in one boot (configuration changed each time): none fails,
//!    both pages are erased and evenly (the erase counts the board logs), and the board
//!    latched no fault and logged no overrun while saving (0 missed deadlines).

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, ensure, Context, Result};
use client::qemu::{Board as ClientBoard, LogSink, QemuBoard, QemuOptions};
use client::{Client, ErrorCode, Limits, State};

use crate::board::Board;
use crate::cmd::{cargo, target_dir};
use crate::defmt_log::LogFormat;

/// What the check sets and reads back: clutch length µm, current limit mA, clutch
/// tolerance µm.
type Settings = (u32, u16, u16);
/// The configuration saved first (the "old" one of the cut sweeps): clutch 5 mm, 1.2 A,
/// tolerance 0.6 mm.
const OLD: Settings = (5_000, 1_200, 600);
/// The one saved over it (the "new" one): clutch 2 mm, 1.0 A, tolerance 1 mm.
const NEW: Settings = (2_000, 1_000, 1_000);
/// The firmware's defaults (a factory reset's result): clutch 3 mm, 1.5 A, no tolerance.
const DEFAULT: Settings = (3_000, 1_500, 0);

/// Saves in the wear check (`VSA_PERSISTENCE_SAVES` overrides).
const SAVES: u32 = 1_000;

/// QEMU's exit status after an injected power cut (the firmware's `POWER_CUT_EXIT`).
const POWER_CUT_EXIT: i32 = 3;

/// What the test measured.
pub struct Report {
    /// Word writes of one save and of one factory reset.
    pub save_words: u64,
    /// Word writes of one factory reset.
    pub reset_words: u64,
    /// Cuts swept in the save, and how many booted with the old and the new set.
    pub save_cuts: (usize, usize, usize),
    /// The same for the factory reset.
    pub reset_cuts: (usize, usize, usize),
    /// Saves in the wear check and the page erase counts after them.
    pub saves: u32,
    /// Page erase counts after the saves.
    pub erases: [u64; 2],
    /// Wall-clock seconds of the saves.
    pub saves_secs: f64,
}

impl std::fmt::Display for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "save + power cycle: configuration back; save while enabled refused; power cut \
             after each of the {} word writes of a save: {} boots, {} with the old set, {} \
             with the new, none mixed or refused; after each of the {} of a factory reset: \
             {} boots, {} old, {} reset; {} saves in {:.1} s: page erases {:?}, no fault, no \
             overrun",
            self.save_words,
            self.save_cuts.0,
            self.save_cuts.1,
            self.save_cuts.2,
            self.reset_words,
            self.reset_cuts.0,
            self.reset_cuts.1,
            self.reset_cuts.2,
            self.saves,
            self.saves_secs,
            self.erases
        )
    }
}

/// A running board and its log.
struct Running {
    qemu: QemuBoard,
    client: Client,
    log: mpsc::Receiver<Vec<u8>>,
}

/// The test's state: the board, its ELF and log format, its scratch directory.
struct Rig<'a> {
    board: ClientBoard,
    elf: &'a Path,
    format: LogFormat,
    dir: PathBuf,
}

fn err(what: &'static str) -> impl Fn(client::Error) -> anyhow::Error {
    move |e| anyhow!("{what}: {e}")
}

impl Rig<'_> {
    fn file(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Boots the board serving the protocol with its flash in `flash`.
    fn boot(&self, flash: &Path, cut_after: Option<u64>) -> Result<Running> {
        let mut opts = QemuOptions::new(self.board, self.elf);
        let path = client::qemu::flash_file_arg(flash).map_err(|e| anyhow!(e))?;
        opts.firmware_args = vec!["--flash".into(), path];
        if let Some(n) = cut_after {
            opts.firmware_args
                .extend(["--flash-cut-after".into(), n.to_string()]);
        }
        let (tx, log) = mpsc::channel();
        let (qemu, transport) = QemuBoard::spawn(&opts, LogSink::Channel(tx))
            .map_err(|e| anyhow!("starting the emulated board: {e}"))?;
        let mut client = Client::new(transport);
        client
            .wait_ready(Duration::from_secs(10), Duration::from_millis(20))
            .map_err(err("the board did not answer after boot"))?;
        Ok(Running { qemu, client, log })
    }

    /// Stops the board (power off) and returns its decoded log.
    fn stop(&self, r: Running) -> Vec<String> {
        let Running {
            mut qemu,
            client,
            log,
        } = r;
        drop(client);
        qemu.kill();
        self.lines(&log)
    }

    fn lines(&self, log: &mpsc::Receiver<Vec<u8>>) -> Vec<String> {
        let mut decoder = self.format.decoder();
        let mut lines = Vec::new();
        while let Ok(bytes) = log.recv_timeout(Duration::from_secs(5)) {
            lines.extend(decoder.feed(&bytes));
        }
        lines
    }

    /// Boots from `flash` and returns the configuration it came up with and its log;
    /// checks it answers, is disabled with no fault and rejected no record.
    fn boot_and_read(&self, flash: &Path) -> Result<(Settings, Vec<String>)> {
        let mut r = self.boot(flash, None)?;
        let st = r.client.status().map_err(err("status"))?;
        let limits = r.client.limits().map_err(err("limits"))?;
        let lines = self.stop(r);
        ensure!(
            st.state == State::Disabled && st.faults.is_empty(),
            "booted {:?} with faults {:?}",
            st.state,
            st.faults
        );
        if let Some(l) = lines.iter().find(|l| l.contains("rejected")) {
            bail!("a record was rejected at boot: {l}");
        }
        Ok((
            (
                st.clutch_length_um,
                limits.current_ma,
                limits.clutch_tolerance_um,
            ),
            lines,
        ))
    }
}

fn configure(c: &mut Client, (clutch_um, current_ma, clutch_tolerance_um): Settings) -> Result<()> {
    c.set_clutch_length(clutch_um).map_err(err("clutch"))?;
    c.set_limits(&Limits {
        current_ma,
        clutch_tolerance_um,
        ..Limits::DEFAULT
    })
    .map_err(err("limits"))
}

/// `(words, words since boot)` of the last `store: OP: …` line.
fn op_words(lines: &[String], op: &str) -> Result<(u64, u64)> {
    let tag = format!("store: {op}: ");
    let line = lines
        .iter()
        .rev()
        .find_map(|l| l.split_once(&tag).map(|(_, rest)| rest))
        .with_context(|| format!("no `{tag}` line in the board's log"))?;
    let num = |s: &str| -> Result<u64> {
        s.trim_matches(|c: char| !c.is_ascii_digit())
            .parse()
            .with_context(|| format!("reading `{line}`"))
    };
    let (words, rest) = line.split_once(" word writes").context("word writes")?;
    let since = rest
        .split_once("since boot ")
        .and_then(|(_, r)| r.split_once(')'))
        .context("since boot")?
        .0;
    Ok((num(words)?, num(since)?))
}

/// The page erase counts of the last store line.
fn erase_counts(lines: &[String]) -> Result<[u64; 2]> {
    let line = lines
        .iter()
        .rev()
        .find(|l| l.contains("page erases since boot ["))
        .context("no page erase counts in the log")?;
    let inside = line
        .split_once('[')
        .and_then(|(_, r)| r.split_once(']'))
        .context("erase counts")?
        .0;
    let mut counts = inside.split(", ").map(str::parse::<u64>);
    match (counts.next(), counts.next()) {
        (Some(Ok(a)), Some(Ok(b))) => Ok([a, b]),
        _ => bail!("erase counts in `{line}`"),
    }
}

/// Which cuts to sweep out of `words` (`VSA_PERSISTENCE_CUTS=N`: every N-th; default
/// every one).
fn cuts(words: u64) -> Vec<u64> {
    let stride = std::env::var("VSA_PERSISTENCE_CUTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .filter(|s| *s > 0)
        .unwrap_or(1);
    let mut v: Vec<u64> = (1..=words).step_by(stride).collect();
    if v.last() != Some(&words) {
        v.push(words);
    }
    v
}

/// Cuts the power after word write `boot_words + n` while `op` runs on a copy of `base`,
/// then boots that copy: returns the configuration it came up with.
fn cut_and_boot(
    rig: &Rig<'_>,
    base: &Path,
    cut_at: u64,
    op: impl Fn(&mut Client) -> Result<()>,
) -> Result<Settings> {
    let file = rig.file("cut.bin");
    std::fs::copy(base, &file).context("copying the flash file")?;
    let mut r = rig.boot(&file, Some(cut_at))?;
    let answered = op(&mut r.client);
    let t = Instant::now();
    let status = loop {
        if let Some(s) = r.qemu.try_wait() {
            break s;
        }
        ensure!(
            t.elapsed() < Duration::from_secs(10),
            "the board did not lose power at word write {cut_at} (answered {answered:?})"
        );
        std::thread::sleep(Duration::from_millis(5));
    };
    let lines = rig.stop(r);
    ensure!(
        status.code() == Some(POWER_CUT_EXIT),
        "cut at word write {cut_at}: exit status {status:?}, log: {:?}",
        lines.last()
    );
    Ok(rig.boot_and_read(&file)?.0)
}

/// Cuts the power after each of the `words` word writes of `op` (after `boot_words` of
/// boot) on a copy of `base` and boots each copy: every boot must come up with `before` or
/// `after` (`what` names the operation). Returns (cuts, boots with `before`, boots with
/// `after`).
fn sweep(
    rig: &Rig<'_>,
    base: &Path,
    boot_words: u64,
    words: u64,
    (what, before, after): (&str, Settings, Settings),
    op: impl Fn(&mut Client) -> Result<()>,
) -> Result<(usize, usize, usize)> {
    let mut tally = (0, 0, 0);
    for n in cuts(words) {
        let got = cut_and_boot(rig, base, boot_words + n, &op)?;
        tally.0 += 1;
        if got == before {
            tally.1 += 1;
        } else if got == after {
            tally.2 += 1;
        } else {
            bail!(
                "cut after {what} word {n}: booted with {got:?}, neither {before:?} nor {after:?}"
            );
        }
    }
    Ok(tally)
}

/// Runs the test on `board` with `elf`.
pub fn run(board: Board, elf: &Path) -> Result<Report> {
    let client_board = match board {
        Board::QemuM4 => ClientBoard::QemuM4,
        Board::QemuM3 => ClientBoard::QemuM3,
        Board::NucleoF446re => bail!("the persistence test runs on an emulated board"),
    };
    let dir = target_dir().join("persistence").join(board.feature());
    std::fs::create_dir_all(&dir)?;
    let rig = Rig {
        board: client_board,
        elf,
        format: LogFormat::from_elf(elf)?,
        dir,
    };
    let flash = rig.file("flash.bin");
    let _ = std::fs::remove_file(&flash);

    // 1. Save, refused while enabled, then power cycle.
    let mut r = rig.boot(&flash, None)?;
    let c = &mut r.client;
    configure(c, OLD)?;
    ensure!(
        c.status().map_err(err("status"))?.differs_from_stored,
        "a changed configuration must differ from the stored one"
    );
    c.enable().map_err(err("enable"))?;
    match c.save() {
        Err(client::Error::Refused {
            code: ErrorCode::NotAllowed,
            ..
        }) => {}
        other => bail!("save while enabled: {other:?}, expected not-allowed"),
    }
    c.disable().map_err(err("disable"))?;
    c.save().map_err(err("save"))?;
    ensure!(
        !c.status().map_err(err("status"))?.differs_from_stored,
        "saved: the running configuration is the stored one"
    );
    rig.stop(r);
    let old_file = rig.file("old.bin");
    std::fs::copy(&flash, &old_file)?;
    vsa_status_shows(&rig, &flash)?;

    // Measure a save and a factory reset on the saved file.
    let mut r = rig.boot(&flash, None)?;
    configure(&mut r.client, NEW)?;
    r.client.save().map_err(err("save"))?;
    let new_file = rig.file("new.bin");
    std::fs::copy(&flash, &new_file)?;
    r.client.factory_reset().map_err(err("factory reset"))?;
    let lines = rig.stop(r);
    let (save_words, save_since_boot) = op_words(&lines, "save")?;
    let (reset_words, reset_since_boot) = op_words(&lines, "factory-reset")?;
    let save_boot = save_since_boot - save_words;
    let reset_boot = reset_since_boot - reset_words - save_words;

    // 2. Power cuts in the save (old → new) and in the factory reset (new → defaults).
    let save_cuts = sweep(
        &rig,
        &old_file,
        save_boot,
        save_words,
        ("save", OLD, NEW),
        |c| {
            configure(c, NEW)?;
            c.save().map_err(err("save"))
        },
    )?;
    let reset_cuts = sweep(
        &rig,
        &new_file,
        reset_boot,
        reset_words,
        ("factory reset", NEW, DEFAULT),
        |c| c.factory_reset().map_err(err("factory reset")),
    )?;
    ensure!(
        save_cuts.1 > 0 && save_cuts.2 > 0 && reset_cuts.1 > 0 && reset_cuts.2 > 0,
        "the sweeps must see both outcomes: save {save_cuts:?}, reset {reset_cuts:?}"
    );

    // 3. Wear: many saves in one boot.
    let saves = std::env::var("VSA_PERSISTENCE_SAVES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(SAVES);
    let mut r = rig.boot(&flash, None)?;
    let t = Instant::now();
    for i in 0..saves {
        let clutch = if i % 2 == 0 { OLD.0 } else { NEW.0 };
        r.client.set_clutch_length(clutch).map_err(err("clutch"))?;
        r.client
            .save()
            .map_err(|e| anyhow!("save {} of {saves}: {e}", i + 1))?;
    }
    let saves_secs = t.elapsed().as_secs_f64();
    let st = r.client.status().map_err(err("status"))?;
    let lines = rig.stop(r);
    ensure!(
        st.faults.is_empty(),
        "faults after the saves: {:?}",
        st.faults
    );
    if let Some(l) = lines.iter().find(|l| l.contains("overruns")) {
        bail!("the board logged an overrun while saving: {l}");
    }
    let erases = erase_counts(&lines)?;
    ensure!(
        erases[0] > 0 && erases[1] > 0 && erases[0].abs_diff(erases[1]) <= 1,
        "page erases after {saves} saves: {erases:?}, expected both pages, evenly"
    );
    Ok(Report {
        save_words,
        reset_words,
        save_cuts,
        reset_cuts,
        saves,
        erases,
        saves_secs,
    })
}

/// `vsa --qemu --qemu-flash FILE status` (the `vsa` tool itself) shows the saved
/// configuration and that it is the stored one.
fn vsa_status_shows(rig: &Rig<'_>, flash: &Path) -> Result<()> {
    let board = match rig.board {
        ClientBoard::QemuM4 => "qemu-m4",
        ClientBoard::QemuM3 => "qemu-m3",
    };
    let out = cargo()
        .args([
            "run", "-q", "-p", "vsa-cli", "--", "--qemu", "--board", board,
        ])
        .arg("--elf")
        .arg(rig.elf)
        .arg("--qemu-flash")
        .arg(flash)
        .arg("status")
        .output()
        .context("running vsa status")?;
    let text = String::from_utf8_lossy(&out.stdout);
    ensure!(
        out.status.success(),
        "vsa status failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let has = |k: &str, v: &str| {
        text.lines()
            .any(|l| l.starts_with(k) && l.trim_end().ends_with(v))
    };
    ensure!(
        has("clutch length", "5 mm") && has("stored config", "same as the running one"),
        "after the power cycle `vsa status` shows:\n{text}"
    );
    Ok(())
}
