//! CPU features, detected once for the whole family.
//!
//! Every SIMD site asks this module, never `is_x86_feature_detected!` itself, so that one
//! switch selects the portable code everywhere: `HDRCODEC_CPU=scalar` (the portable twins only),
//! `HDRCODEC_CPU=avx2` (the AVX2 kernels, not the BMI2 ones), `HDRCODEC_CPU=bmi2` (all but the
//! AVX-512 ones) or `HDRCODEC_CPU=avx512` (everything). The variable can only lower the level
//! the hardware has, so a kernel chosen through [`level`] is always safe to run. CI runs the
//! codec tests once more with `HDRCODEC_CPU=scalar`.

use std::sync::OnceLock;

/// The instruction-set levels the family's kernels are written for, in increasing order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[non_exhaustive]
pub enum CpuLevel {
    /// Portable Rust only (whatever the compiler's baseline target allows).
    Scalar,
    /// x86-64 with AVX2, FMA and F16C (Haswell and later, Zen and later).
    Avx2,
    /// [`Avx2`](CpuLevel::Avx2) and the scalar bit-manipulation extensions BMI1, BMI2 and
    /// LZCNT (`shlx`/`shrx`, `bzhi`, `pext`: shifts by any register, which the entropy decoders'
    /// serial loops use). Every CPU with AVX2 that x86-64-v3 names has them (Haswell and
    /// later, Zen and later); the level is separate so that `HDRCODEC_CPU=avx2` can leave
    /// them out.
    Bmi2,
    /// [`Bmi2`](CpuLevel::Bmi2) and AVX-512F (Skylake-SP, Ice Lake, Zen 4 and later): the
    /// kernels whose sixteen 32-bit lanes a register pay on the cores that run 512-bit
    /// operations at full width. Their twin tests need a CPU with it (see
    /// [`twin_test_can_run`]).
    Avx512,
}

impl CpuLevel {
    /// The name `HDRCODEC_CPU` accepts for this level.
    pub fn name(self) -> &'static str {
        match self {
            CpuLevel::Scalar => "scalar",
            CpuLevel::Avx2 => "avx2",
            CpuLevel::Bmi2 => "bmi2",
            CpuLevel::Avx512 => "avx512",
        }
    }

    /// The level called `name` in `HDRCODEC_CPU` (`scalar`/`portable`/`none`, `avx2`,
    /// `bmi2`/`x86-64-v3`, `avx512`/`native`/`best`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name.trim().to_ascii_lowercase().as_str() {
            "scalar" | "portable" | "none" | "generic" => Some(CpuLevel::Scalar),
            "avx2" => Some(CpuLevel::Avx2),
            "bmi2" | "x86-64-v3" => Some(CpuLevel::Bmi2),
            "avx512" | "native" | "best" => Some(CpuLevel::Avx512),
            _ => None,
        }
    }
}

/// The environment variable that caps the level: `HDRCODEC_CPU=scalar`.
pub const ENV_VAR: &str = "HDRCODEC_CPU";

/// What the hardware supports, ignoring `HDRCODEC_CPU`.
pub fn detected() -> CpuLevel {
    static DETECTED: OnceLock<CpuLevel> = OnceLock::new();
    *DETECTED.get_or_init(detect)
}

#[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
fn detect() -> CpuLevel {
    if std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("fma")
        && std::arch::is_x86_feature_detected!("f16c")
    {
        if std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                CpuLevel::Avx512
            } else {
                CpuLevel::Bmi2
            }
        } else {
            CpuLevel::Avx2
        }
    } else {
        CpuLevel::Scalar
    }
}

#[cfg(not(any(target_arch = "x86", target_arch = "x86_64")))]
fn detect() -> CpuLevel {
    CpuLevel::Scalar
}

/// The level the kernels use: the hardware's, capped by `HDRCODEC_CPU` (read once). An
/// unknown value of the variable is ignored with a message on stderr.
#[inline]
pub fn level() -> CpuLevel {
    static LEVEL: OnceLock<CpuLevel> = OnceLock::new();
    *LEVEL.get_or_init(|| {
        let hw = detected();
        match std::env::var(ENV_VAR) {
            Err(_) => hw,
            Ok(v) => match CpuLevel::from_name(&v) {
                Some(cap) => hw.min(cap),
                None => {
                    eprintln!("hdrcodec: ignoring {ENV_VAR}={v} (known: scalar, avx2, bmi2, avx512)");
                    hw
                }
            },
        }
    })
}

/// True when the AVX2 (+FMA, F16C) kernels may run: the hardware has them and
/// `HDRCODEC_CPU` does not forbid them.
#[inline]
pub fn avx2() -> bool {
    level() >= CpuLevel::Avx2
}

/// True when the BMI2 kernels may run: the hardware has AVX2 (+FMA, F16C), BMI1, BMI2 and
/// LZCNT, and `HDRCODEC_CPU` does not forbid them.
#[inline]
pub fn bmi2() -> bool {
    level() >= CpuLevel::Bmi2
}

/// True when the AVX-512 kernels may run: the hardware has [`bmi2`]'s features and AVX-512F,
/// and `HDRCODEC_CPU` does not forbid them.
#[inline]
pub fn avx512() -> bool {
    level() >= CpuLevel::Avx512
}

/// For a test that compares a SIMD kernel with its portable twin: true when the hardware can
/// run the kernel at `needed` (the override does not matter: the test calls both directly).
/// When it cannot, the test has nothing to compare: under `CI=true` that is a failure (the CI
/// machine must exercise every kernel), elsewhere it prints `SKIPPED` and the test returns.
/// AVX-512 is the exception: x86-64 machines without it are common (CI's among them, for all
/// we know), so its twin tests print `SKIPPED` there under CI too; CI prints the CPU's flags.
pub fn twin_test_can_run(needed: CpuLevel, test: &str) -> bool {
    if detected() >= needed {
        return true;
    }
    let ci = needed < CpuLevel::Avx512 && std::env::var("CI").is_ok_and(|v| v == "true" || v == "1");
    assert!(!ci, "{test}: this CPU lacks {} (CI=true requires every SIMD kernel to be tested)", needed.name());
    eprintln!("SKIPPED {test}: this CPU lacks {}", needed.name());
    false
}

/// Set in the child process of [`check_portable_path_in_child`]: the digest it must reproduce.
const PORTABLE_DIGEST: &str = "HDRCODEC_PORTABLE_DIGEST";

/// For a test that checks, through a codec's public API, that the portable path gives what the
/// SIMD path gives. In the test process it computes `digest`, runs the test binary again on
/// `test` (the calling test's exact name) with `HDRCODEC_CPU=scalar`, and panics unless that
/// child passes; in the child it checks that the level is scalar and that `digest` is the same.
/// The variable is read once per process, so the portable run needs a process of its own.
pub fn check_portable_path_in_child(test: &str, digest: impl Fn() -> u64) {
    if let Ok(want) = std::env::var(PORTABLE_DIGEST) {
        assert_eq!(level(), CpuLevel::Scalar, "the child runs with {ENV_VAR}=scalar");
        assert_eq!(format!("{:016x}", digest()), want, "the portable path differs from the parent's");
        return;
    }
    let here = format!("{:016x}", digest());
    let exe = std::env::current_exe().expect("the test binary's path");
    let out = std::process::Command::new(exe)
        .args(["--exact", test, "--test-threads=1"])
        .env(ENV_VAR, "scalar")
        .env(PORTABLE_DIGEST, &here)
        .output()
        .expect("run the test binary again");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("1 passed"),
        "parent at {:?}: {stdout}{}",
        level(),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_override_only_lowers_the_level() {
        assert!(level() <= detected());
        assert_eq!(CpuLevel::from_name(" Scalar "), Some(CpuLevel::Scalar));
        assert_eq!(CpuLevel::from_name("avx2"), Some(CpuLevel::Avx2));
        assert_eq!(CpuLevel::from_name("BMI2"), Some(CpuLevel::Bmi2));
        assert_eq!(CpuLevel::from_name("native"), Some(CpuLevel::Avx512));
        assert_eq!(CpuLevel::from_name("AVX512"), Some(CpuLevel::Avx512));
        assert_eq!(CpuLevel::from_name("avx10"), None);
        assert!(
            CpuLevel::Scalar < CpuLevel::Avx2 && CpuLevel::Avx2 < CpuLevel::Bmi2 && CpuLevel::Bmi2 < CpuLevel::Avx512
        );
        for level in [CpuLevel::Scalar, CpuLevel::Avx2, CpuLevel::Bmi2, CpuLevel::Avx512] {
            assert_eq!(CpuLevel::from_name(level.name()), Some(level));
        }
        match std::env::var(ENV_VAR).ok().and_then(|v| CpuLevel::from_name(&v)) {
            Some(CpuLevel::Scalar) => assert!(!avx2() && !bmi2()),
            Some(CpuLevel::Avx2) => assert!(!bmi2()),
            Some(CpuLevel::Bmi2) => assert!(!avx512()),
            _ => assert_eq!(level(), detected()),
        }
    }

    /// The variable is read once, when a process first asks, so each value is tried in a fresh
    /// process: this test binary run again on [`child_reports_its_level`] only.
    #[test]
    fn the_variable_sets_the_level_of_a_fresh_process() {
        let exe = std::env::current_exe().expect("the test binary's path");
        let hw = detected();
        for (value, want) in [
            ("scalar", CpuLevel::Scalar),
            ("portable", CpuLevel::Scalar),
            ("avx2", hw.min(CpuLevel::Avx2)),
            ("bmi2", hw.min(CpuLevel::Bmi2)),
            ("avx512", hw.min(CpuLevel::Avx512)),
            ("avx10", hw), // unknown: ignored (with a message on stderr)
        ] {
            let out = std::process::Command::new(&exe)
                .args(["--exact", "cpu::tests::child_reports_its_level", "--test-threads=1"])
                .env(ENV_VAR, value)
                .env(CHILD_WANTS, want.name())
                .output()
                .expect("run the test binary again");
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(
                out.status.success() && stdout.contains("1 passed"),
                "{ENV_VAR}={value}: {stdout}{}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }

    /// Set in the child process run by the test above: the level it must see.
    const CHILD_WANTS: &str = "HDRCODEC_CPU_TEST_WANTS";

    /// Checks the level in the child process (and nothing elsewhere).
    #[test]
    fn child_reports_its_level() {
        let Ok(want) = std::env::var(CHILD_WANTS) else { return };
        assert_eq!(level().name(), want);
        assert_eq!(avx2(), ["avx2", "bmi2", "avx512"].contains(&want.as_str()));
        assert_eq!(bmi2(), ["bmi2", "avx512"].contains(&want.as_str()));
        assert_eq!(avx512(), want == "avx512");
        assert!(level() <= detected());
    }
}
