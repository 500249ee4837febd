//! Which vector instruction set the tile paths of
//! [`Object::intersect_tile`](crate::Object::intersect_tile) run with.
//!
//! The tile's base pass, its support filter and the lane walk are each
//! compiled three times, for AVX-512, for AVX2 and for the x86-64 baseline
//! (SSE2), and one is chosen at run time from what the processor offers.
//! Their results are identical to the last bit (IEEE operations are exact
//! whatever the vector width, and no multiply-add is fused), so the choice
//! changes only the speed.
//!
//! The environment variable `ISOLUX_SIMD` caps the choice, so that one
//! machine can measure what another without AVX-512 (or AVX2) would get:
//!
//! | value | instruction set used |
//! |---|---|
//! | unset, `best` | the best the processor has |
//! | `avx512` | the same (AVX-512 is the widest) |
//! | `avx2` | AVX2 at most |
//! | `sse2`, `baseline` | the x86-64 baseline |
//!
//! An unknown value is reported once on stderr and the best set is used.
//! It is read once per process.
//!
//! ```
//! // Whatever the cap, the answer is one of the three levels.
//! let isa = isolux_geometry::simd::isa();
//! assert!(matches!(isa, isolux_geometry::simd::Isa::Avx512
//!     | isolux_geometry::simd::Isa::Avx2 | isolux_geometry::simd::Isa::Baseline));
//! ```

use std::sync::OnceLock;

/// An instruction set for the vectorized tile paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Isa {
    /// The x86-64 baseline (SSE2), or any other architecture.
    Baseline,
    /// AVX2.
    Avx2,
    /// AVX-512F.
    Avx512,
}

impl Isa {
    /// The name `ISOLUX_SIMD` takes for this level.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "sse2",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }
}

/// The best set this processor has.
fn detected() -> Isa {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            return Isa::Avx512;
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            return Isa::Avx2;
        }
    }
    Isa::Baseline
}

/// The cap an `ISOLUX_SIMD` value sets; `None` for an unknown value.
fn parse_cap(value: &str) -> Option<Isa> {
    match value.trim().to_ascii_lowercase().as_str() {
        "" | "best" | "avx512" => Some(Isa::Avx512),
        "avx2" => Some(Isa::Avx2),
        "sse2" | "baseline" => Some(Isa::Baseline),
        _ => None,
    }
}

/// The level `best` capped by an `ISOLUX_SIMD` value (`None`: unset), and
/// the warning an unknown value earns.
fn capped(best: Isa, value: Option<&str>) -> (Isa, Option<String>) {
    match value.map(|v| (v, parse_cap(v))) {
        None => (best, None),
        Some((_, Some(cap))) => (best.min(cap), None),
        Some((v, None)) => (
            best,
            Some(format!(
                "warning: ISOLUX_SIMD={v:?} is not one of best, avx512, avx2, sse2; using {}",
                best.name()
            )),
        ),
    }
}

/// The level chosen for this process: the detected one, capped by
/// `ISOLUX_SIMD`.
fn chosen() -> Isa {
    static CHOSEN: OnceLock<Isa> = OnceLock::new();
    *CHOSEN.get_or_init(|| {
        let value = std::env::var("ISOLUX_SIMD").ok();
        let (isa, warning) = capped(detected(), value.as_deref());
        if let Some(w) = warning {
            eprintln!("{w}");
        }
        isa
    })
}

#[cfg(test)]
thread_local! {
    /// For the tests: a further cap on this thread's level (`None`: none).
    pub(crate) static FORCE: std::cell::Cell<Option<Isa>> = const { std::cell::Cell::new(None) };
}

/// The instruction set the tile paths use now.
pub fn isa() -> Isa {
    let isa = chosen();
    #[cfg(test)]
    if let Some(cap) = FORCE.with(|f| f.get()) {
        return isa.min(cap);
    }
    isa
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn caps_parse_and_unknown_values_are_refused() {
        assert_eq!(parse_cap("AVX2"), Some(Isa::Avx2));
        assert_eq!(parse_cap(" sse2 "), Some(Isa::Baseline));
        assert_eq!(parse_cap("baseline"), Some(Isa::Baseline));
        assert_eq!(parse_cap("best"), Some(Isa::Avx512));
        assert_eq!(parse_cap("neon"), None);
        // A cap lowers the level, never raises it above the processor's.
        assert_eq!(capped(Isa::Avx512, Some("avx2")), (Isa::Avx2, None));
        assert_eq!(capped(Isa::Avx2, Some("avx512")), (Isa::Avx2, None));
        assert_eq!(capped(Isa::Avx2, Some("sse2")), (Isa::Baseline, None));
        assert_eq!(capped(Isa::Avx2, None), (Isa::Avx2, None));
        // An unknown value keeps the best level and says so, naming it.
        let (isa, warning) = capped(Isa::Avx2, Some("neon"));
        assert_eq!(isa, Isa::Avx2);
        assert!(warning.is_some_and(|w| w.contains("\"neon\"") && w.contains("avx2")));
    }

    #[test]
    fn the_test_cap_lowers_the_level() {
        FORCE.with(|f| f.set(Some(Isa::Baseline)));
        assert_eq!(isa(), Isa::Baseline);
        FORCE.with(|f| f.set(None));
        assert_eq!(isa(), chosen());
    }
}
