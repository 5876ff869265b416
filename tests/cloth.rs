//! Cloth bodies and contacts between bodies: the paper's ball-on-cloth scene from its file,
//! gradients through soft-cloth contact against finite differences, and bad cloth input.

mod common;

use diffsoft::diff::Mode;
use diffsoft::verify::gradients::{self, check_case};

#[test]
fn ball_on_cloth_gradients_match_finite_differences() {
    let case = gradients::ball_on_cloth(12).unwrap();
    let c = check_case(&case, 7);
    assert!(c.error.is_none(), "{:?}", c.error);
    let m = &c.modes[0];
    assert_eq!(m.mode, Mode::Unrolled);
    for g in &m.groups {
        eprintln!(
            "{}: analytic {:e}, best fd {:e} (step {:e}), rel {:e}",
            g.group, g.analytic, g.fd_best, g.step_best, g.rel_error_best
        );
    }
    for g in &m.groups {
        assert!(
            g.passes,
            "{}: analytic {:e}, best fd {:e} (step {:e}), rel {:e}",
            g.group, g.analytic, g.fd_best, g.step_best, g.rel_error_best
        );
    }
}
