//! Progress of long encodes and decodes, for a caller's progress bar.
//!
//! [`observe`] runs some work with an observer installed on the current thread; the
//! coder reports to it after each transform and each bit-plane pass. Nothing is
//! reported (and nothing costs) when no observer is installed.

use std::cell::RefCell;
use std::rc::Rc;

/// What the codec is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Stage {
    /// The wavelet transform (forward or inverse).
    Transform,
    /// Bit-plane passes of the zerotree coder.
    Coding,
    /// Whole tiles of a tiled file (a unit is one sample of a finished tile).
    Tiles,
}

impl Stage {
    /// A short name for messages.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Transform => "transform",
            Stage::Coding => "coding",
            Stage::Tiles => "tiles",
        }
    }
}

/// How far an encode or decode has got: `done` of `total` units of work, where a unit
/// is one sample through one stage step (the transform, or one pass).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct Progress {
    /// The stage reporting.
    pub stage: Stage,
    /// Units done, at most `total`.
    pub done: u64,
    /// Units the whole run is expected to take (it may grow once the number of passes
    /// is known).
    pub total: u64,
}

type Observer = Rc<dyn Fn(Progress)>;

thread_local! {
    static OBSERVER: RefCell<Option<Observer>> = const { RefCell::new(None) };
}

/// Runs `work` with `observer` receiving the progress of every encode and decode it
/// makes on this thread; the previous observer (if any) is back afterwards.
pub fn observe<T>(observer: impl Fn(Progress) + 'static, work: impl FnOnce() -> T) -> T {
    struct Restore(Option<Observer>);
    impl Drop for Restore {
        fn drop(&mut self) {
            let previous = self.0.take();
            OBSERVER.with(|o| *o.borrow_mut() = previous);
        }
    }
    let previous = OBSERVER.with(|o| o.borrow_mut().replace(Rc::new(observer)));
    let _restore = Restore(previous);
    work()
}

/// Reports progress to the observer installed by [`observe`], if any.
pub(crate) fn report(stage: Stage, done: u64, total: u64) {
    let observer = OBSERVER.with(|o| o.borrow().clone());
    if let Some(observer) = observer {
        observer(Progress {
            stage,
            done: done.min(total),
            total,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    #[test]
    fn observer_sees_reports_only_inside_observe() {
        let seen = Rc::new(RefCell::new(Vec::new()));
        report(Stage::Coding, 1, 2);
        let log = seen.clone();
        let out = observe(
            move |p| log.borrow_mut().push(p),
            || {
                report(Stage::Transform, 5, 10);
                report(Stage::Coding, 12, 10);
                7
            },
        );
        report(Stage::Coding, 2, 2);
        assert_eq!(out, 7);
        let seen = seen.borrow();
        assert_eq!(seen.len(), 2);
        assert_eq!(
            (seen[0].stage, seen[0].done, seen[0].total),
            (Stage::Transform, 5, 10)
        );
        assert_eq!(seen[1].done, 10, "done is clamped to total");
    }

    /// Everything reported while `work` runs.
    fn reports(work: impl FnOnce()) -> Vec<Progress> {
        let seen = Rc::new(RefCell::new(Vec::new()));
        let log = seen.clone();
        observe(move |p| log.borrow_mut().push(p), work);
        let out = seen.borrow().clone();
        out
    }

    /// Fractions never fall and the run ends at 100 %.
    fn assert_advances_to_the_end(seen: &[Progress]) {
        assert!(seen.len() >= 3, "{seen:?}");
        let fractions: Vec<f64> = seen
            .iter()
            .map(|p| p.done as f64 / p.total as f64)
            .collect();
        assert!(fractions.windows(2).all(|w| w[0] <= w[1]), "{fractions:?}");
        let last = seen.last().unwrap();
        assert_eq!(last.done, last.total);
    }

    #[test]
    fn encode_and_decode_report_every_pass_up_to_the_end() {
        use crate::{decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, Samples};
        let heights = (0..61 * 47).map(|i| ((i * 7919) % 1000) as i16).collect();
        let raster = Raster::new(61, 47, Samples::I16(heights)).unwrap();
        let mut file = Vec::new();
        let encoding = reports(|| {
            file = encode(&raster, &EncodeOptions::new(Quality::Lossless, None))
                .unwrap()
                .bytes;
        });
        assert_eq!(encoding[0].stage, Stage::Transform);
        assert_advances_to_the_end(&encoding);
        let decoding = reports(|| {
            decode(&file, &DecodeOptions::default()).unwrap();
        });
        assert_eq!(decoding.last().unwrap().stage, Stage::Transform);
        assert_advances_to_the_end(&decoding);
    }
}
