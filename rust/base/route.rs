//! Which of the core's hand-written vector routes runs: the processor's
//! widest, or a narrower one asked for by the environment variable
//! [`SWITCH`] (`LPVID_KERNEL`).
//!
//! The routes differ only in the code that the core chooses at run time:
//! the Gram products of the Gauss-Newton evaluation
//! ([`crate::base::gram_product`]: 16 x 12 blocks on AVX-512F, 8 x 6 on AVX2 and
//! FMA, a plain loop otherwise), the packing of their panels and the
//! simulation and time-record kernels (`pulp`'s AVX2 code or the plain
//! loops). Everything else (faer, Clarabel, the compiler's own code) is the
//! same on every route of one build.
//!
//! - `avx512`: the AVX-512 Gram kernel (processors with AVX-512F);
//! - `avx2`: what a processor with AVX2 and FMA but without AVX-512 runs
//!   (most laptops, AMD Zen 2 and 3): the AVX2 kernels;
//! - `portable`: no hand-written vector code at all (plain loops; the
//!   compiler still vectorises them for the build's target);
//! - unset, empty or `auto`: the processor's widest.
//!
//! A route the processor lacks is refused by `import lpvid`
//! (`python/lpvid/_cpu.py`); here it falls back to the widest the
//! processor runs. The variable is read once, at the first use.

use std::sync::OnceLock;

/// The environment variable that chooses the route.
pub const SWITCH: &str = "LPVID_KERNEL";

/// A route, from the narrowest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Route {
    /// Plain loops only.
    Portable,
    /// AVX2 and FMA.
    Avx2,
    /// AVX-512F (and AVX2 and FMA where AVX-512 has no kernel).
    Avx512,
}

impl Route {
    /// The widest route this processor runs.
    pub fn detected() -> Route {
        #[cfg(target_arch = "x86_64")]
        {
            let avx2 = std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma");
            if avx2 && std::arch::is_x86_feature_detected!("avx512f") {
                return Route::Avx512;
            }
            if avx2 {
                return Route::Avx2;
            }
        }
        Route::Portable
    }

    /// The route named by `value` (`None` for the processor's widest).
    ///
    /// # Errors
    /// A message naming the value and the ones allowed.
    pub fn parse(value: &str) -> Result<Option<Route>, String> {
        match value.trim().to_ascii_lowercase().as_str() {
            "" | "auto" => Ok(None),
            "avx512" => Ok(Some(Route::Avx512)),
            "avx2" => Ok(Some(Route::Avx2)),
            "portable" => Ok(Some(Route::Portable)),
            other => Err(format!(
                "{SWITCH}={other:?}: expected one of auto, avx512, avx2, portable"
            )),
        }
    }

    /// The route the core runs: the one [`SWITCH`] asks for, never wider
    /// than [`Route::detected`]; the widest when it is unset or unknown.
    pub fn current() -> Route {
        static CURRENT: OnceLock<Route> = OnceLock::new();
        *CURRENT.get_or_init(|| {
            let asked = std::env::var(SWITCH).ok();
            let asked = asked.as_deref().map(Route::parse);
            let detected = Route::detected();
            match asked {
                Some(Ok(Some(route))) => route.min(detected),
                _ => detected,
            }
        })
    }

    /// Whether the core may run its AVX2 and FMA code.
    pub fn avx2() -> bool {
        Route::current() >= Route::Avx2
    }

    /// The route's name, as [`SWITCH`] spells it.
    pub fn name(self) -> &'static str {
        match self {
            Route::Portable => "portable",
            Route::Avx2 => "avx2",
            Route::Avx512 => "avx512",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_to_their_route() {
        for route in [Route::Portable, Route::Avx2, Route::Avx512] {
            assert_eq!(Route::parse(route.name()), Ok(Some(route)));
        }
        assert_eq!(Route::parse(" AVX2 "), Ok(Some(Route::Avx2)));
        assert_eq!(Route::parse("auto"), Ok(None));
        assert_eq!(Route::parse(""), Ok(None));
        let err = Route::parse("sse").unwrap_err();
        assert!(
            err.contains("LPVID_KERNEL") && err.contains("portable"),
            "{err}"
        );
    }

    #[test]
    fn the_current_route_is_never_wider_than_the_processor() {
        assert!(Route::current() <= Route::detected());
        match std::env::var(SWITCH).ok().map(|v| Route::parse(&v)) {
            Some(Ok(Some(asked))) => assert_eq!(Route::current(), asked.min(Route::detected())),
            _ => assert_eq!(Route::current(), Route::detected()),
        }
    }
}
