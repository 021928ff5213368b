//! The options of one run (what to run, for how long, how to idle), and their parser for
//! the emulated boards' command line.

/// Options of one run, from the QEMU command line (semihosting) on the emulated boards.
pub struct RunConfig {
    /// Stop after this many seconds of the independent clock; `None` runs forever.
    pub seconds: Option<u32>,
    /// How `idle` waits for the next interrupt.
    pub idle: IdleMode,
    /// Panic or fault on purpose in a control tick, to prove the fail-safe: the bridge
    /// goes off, the log stays decodable and the emulator exits with failure.
    pub injection: Option<crate::fail_safe::Injection>,
    /// The scenario to run (emulated boards; default the step sweep).
    #[cfg(feature = "qemu")]
    pub scenario: plant::scenario::ScenarioId,
    /// Serve the host protocol on USART2 with the simulated actuator instead of running a
    /// scenario (emulated boards; `--serve`). Runs until QEMU is stopped or `--seconds`.
    #[cfg(feature = "qemu")]
    pub serve: bool,
    /// While serving: constant load hung on the link at the first driven tick, mN·m
    /// (`--load-mnm N`, |N| ≤ 2000; default 0: nothing attached).
    #[cfg(feature = "qemu")]
    pub serve_load_mnm: i32,
    /// QEMU's `-icount` shift, if the runner passed it: one instruction takes 2^shift ns of
    /// virtual time, so SysTick counts convert to instructions.
    pub icount_shift: Option<u8>,
    /// The host file holding the emulated flash of the settings store (`--flash PATH`,
    /// read at boot and written after every store operation through semihosting); `None`:
    /// no store in a scenario run, a store in RAM only while serving.
    #[cfg(feature = "qemu")]
    pub flash_file: Option<heapless::String<FLASH_PATH_MAX>>,
    /// Cut the emulated flash's power after this many word writes since boot
    /// (`--flash-cut-after N`, N ≥ 1): the firmware then exits at once, the file keeping
    /// exactly the words written.
    #[cfg(feature = "qemu")]
    pub flash_cut_after: Option<u32>,
    /// `--dxl-id N`: the board's ID on the Dynamixel bus (0–252; default 1).
    pub dxl_id: u8,
    /// `--plant NAME=VALUE` (repeatable): the simulated actuator made off-nominal
    /// (`plant::overrides`, its one parser), e.g. `power-up-angle=0.8` for a link powered
    /// up away from the pot's centre with the encoder at zero.
    #[cfg(feature = "qemu")]
    pub plant: plant::overrides::Overrides,
}

/// Longest `--flash` path, bytes.
#[cfg(feature = "qemu")]
pub const FLASH_PATH_MAX: usize = store::FLASH_FILE_PATH_MAX;

/// How the idle loop waits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum IdleMode {
    /// Sleep with WFI until the next interrupt.
    Wfi,
    /// Spin. Under QEMU 7.2 `-icount sleep=off`, a WFI sleep stretches each SysTick period
    /// to two periods of virtual time (see `board::qemu`), so the emulated boards spin.
    Spin,
}

impl RunConfig {
    /// The defaults: run until the scenario ends (emulated boards) or forever.
    pub fn new(idle: IdleMode) -> Self {
        Self {
            seconds: None,
            idle,
            injection: None,
            #[cfg(feature = "qemu")]
            scenario: plant::scenario::ScenarioId::StepSweep,
            #[cfg(feature = "qemu")]
            serve: false,
            #[cfg(feature = "qemu")]
            serve_load_mnm: 0,
            icount_shift: None,
            #[cfg(feature = "qemu")]
            flash_file: None,
            #[cfg(feature = "qemu")]
            flash_cut_after: None,
            dxl_id: 1,
            #[cfg(feature = "qemu")]
            plant: plant::overrides::Overrides::NONE,
        }
    }

    /// Parses `--scenario NAME`, `--serve`, `--seconds N` (stop after N s even if the
    /// scenario has not ended), `--idle wfi|spin`, `--inject-panic-at-tick N`,
    /// `--inject-hardfault-at-tick N`, `--icount-shift N`, `--load-mnm N`, `--flash PATH`,
    /// `--flash-cut-after N` and `--plant NAME=VALUE`.
    pub fn parse<'a>(
        args: impl Iterator<Item = &'a str>,
        default_idle: IdleMode,
    ) -> Result<Self, RunConfigError> {
        let mut config = Self::new(default_idle);
        let mut args = args;
        while let Some(arg) = args.next() {
            match arg {
                #[cfg(feature = "qemu")]
                "--serve" => {
                    config.serve = true;
                }
                "--seconds" => {
                    let value = args.next().ok_or(RunConfigError::MissingValue)?;
                    let seconds: u32 = value.parse().map_err(|_| RunConfigError::BadSeconds)?;
                    if seconds == 0 {
                        return Err(RunConfigError::BadSeconds);
                    }
                    config.seconds = Some(seconds);
                }
                #[cfg(feature = "qemu")]
                "--load-mnm" => {
                    let value = args.next().ok_or(RunConfigError::MissingValue)?;
                    let load: i32 = value.parse().map_err(|_| RunConfigError::BadLoad)?;
                    if load.abs() > 2000 {
                        return Err(RunConfigError::BadLoad);
                    }
                    config.serve_load_mnm = load;
                }
                "--idle" => {
                    config.idle = match args.next().ok_or(RunConfigError::MissingValue)? {
                        "wfi" => IdleMode::Wfi,
                        "spin" => IdleMode::Spin,
                        _ => return Err(RunConfigError::BadIdleMode),
                    };
                }
                "--inject-panic-at-tick" | "--inject-hardfault-at-tick" => {
                    let value = args.next().ok_or(RunConfigError::MissingValue)?;
                    let tick: u32 = value.parse().map_err(|_| RunConfigError::BadTick)?;
                    config.injection = Some(crate::fail_safe::Injection {
                        tick,
                        hardfault: arg == "--inject-hardfault-at-tick",
                    });
                }
                #[cfg(feature = "qemu")]
                "--scenario" => {
                    let name = args.next().ok_or(RunConfigError::MissingValue)?;
                    config.scenario = plant::scenario::ScenarioId::parse(name)
                        .ok_or(RunConfigError::UnknownScenario)?;
                }
                "--icount-shift" => {
                    let value = args.next().ok_or(RunConfigError::MissingValue)?;
                    let shift: u8 = value.parse().map_err(|_| RunConfigError::BadShift)?;
                    if shift > 10 {
                        return Err(RunConfigError::BadShift);
                    }
                    config.icount_shift = Some(shift);
                }
                #[cfg(feature = "qemu")]
                "--flash" => {
                    let path = args.next().ok_or(RunConfigError::MissingValue)?;
                    let mut owned = heapless::String::new();
                    owned
                        .push_str(path)
                        .map_err(|_| RunConfigError::BadFlashPath)?;
                    config.flash_file = Some(owned);
                }
                #[cfg(feature = "qemu")]
                "--flash-cut-after" => {
                    let value = args.next().ok_or(RunConfigError::MissingValue)?;
                    let n: u32 = value.parse().map_err(|_| RunConfigError::BadCut)?;
                    if n == 0 {
                        return Err(RunConfigError::BadCut);
                    }
                    config.flash_cut_after = Some(n);
                }
                #[cfg(feature = "qemu")]
                "--plant" => {
                    let item = args.next().ok_or(RunConfigError::MissingValue)?;
                    config
                        .plant
                        .push_str(item)
                        .map_err(|_| RunConfigError::BadPlant)?;
                }
                "--dxl-id" => {
                    let value = args.next().ok_or(RunConfigError::MissingValue)?;
                    config.dxl_id = value
                        .parse()
                        .ok()
                        .filter(|&id: &u8| id <= 252)
                        .ok_or(RunConfigError::BadDynamixelId)?;
                }
                _ => return Err(RunConfigError::UnknownArgument),
            }
        }
        Ok(config)
    }

    /// Whether the board serves the host (and so applies its stored configuration), rather
    /// than running a scripted scenario with its own (the real board always serves).
    pub fn serves(&self) -> bool {
        #[cfg(feature = "qemu")]
        return self.serve;
        #[cfg(not(feature = "qemu"))]
        return true;
    }

    /// Whether second `second` (1-based) is the last one of the run.
    pub fn is_last_second(&self, second: u32) -> bool {
        self.seconds == Some(second)
    }
}

/// Why the run arguments were rejected.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum RunConfigError {
    /// An option without its value.
    MissingValue,
    /// `--seconds` is not a positive integer.
    BadSeconds,
    /// `--idle` is neither `wfi` nor `spin`.
    BadIdleMode,
    /// `--inject-panic-at-tick` or `--inject-hardfault-at-tick` is not a tick number.
    BadTick,
    /// `--scenario` names no scenario.
    UnknownScenario,
    /// `--icount-shift` is not 0..=10.
    BadShift,
    /// `--load-mnm` is not an integer within ±2000.
    BadLoad,
    /// `--flash` is longer than [`FLASH_PATH_MAX`] bytes.
    BadFlashPath,
    /// `--flash-cut-after` is not a positive integer.
    BadCut,
    /// An argument this firmware does not know.
    UnknownArgument,
    /// `--dxl-id` is not 0..=252.
    BadDynamixelId,
    /// `--plant` is not `NAME=VALUE` of a known parameter within its range.
    BadPlant,
}
