//! Tests of the contact-space solve.

use super::*;
use crate::contact::Contact;
use crate::solver::free_contact::Stencil;

fn ground(index: usize, normal: Vector3<f64>, friction: f64) -> FreeContact {
    FreeContact::single(
        index,
        Contact {
            vertex: index,
            obstacle: 0,
            normal,
            point: Vector3::zeros(),
            anchor: Vector3::new(0.0, 0.1, 0.0),
            friction,
        },
    )
}

/// The contact problem over `contacts` with Delassus matrix `d` and free positions `f`.
fn problem<'a>(contacts: &'a [FreeContact], d: &'a [f64], f: &'a [Vector3<f64>]) -> Problem<'a> {
    Problem { d, f, contacts }
}

/// Three ground contacts with friction 0.3, 0.8 and 0, coupled through `D`, two pushed in
/// and sliding, one apart.
fn three_coupled() -> ([FreeContact; 3], [f64; 9], [Vector3<f64>; 3]) {
    let y = Vector3::y();
    (
        [ground(0, y, 0.3), ground(1, y, 0.8), ground(2, y, 0.0)],
        [1.0, 0.4, 0.1, 0.4, 2.0, 0.3, 0.1, 0.3, 0.5],
        [
            Vector3::new(0.3, -0.2, 0.1),
            Vector3::new(-0.02, -0.1, 0.05),
            Vector3::new(0.01, 0.3, 0.0),
        ],
    )
}

/// Two contacts that ask the same vertex to be above one plane and below another 0.1 m
/// under it: an infeasible set.
fn above_and_below() -> ([FreeContact; 2], [f64; 4], [Vector3<f64>; 2]) {
    let y = Vector3::y();
    let mut below = ground(0, -y, 0.0);
    below.contact.point = Vector3::new(0.0, -0.1, 0.0);
    let mut contacts = [ground(0, y, 0.0), below];
    contacts[1].stencil = Stencil::single(0);
    (contacts, [1.0; 4], [Vector3::new(0.0, -0.5, 0.0); 2])
}

/// The unit normal tilted `deg` degrees from `+y` towards `+x`.
fn tilt(deg: f64) -> Vector3<f64> {
    Vector3::new(deg.to_radians().sin(), deg.to_radians().cos(), 0.0)
}

/// Every contact at `lambda` is not penetrating (to 1e-11 m) and its impulse lies in its
/// friction cone (so it does not pull).
fn assert_feasible(p: &Problem<'_>, lambda: &[Vector3<f64>]) {
    let mut r = Vec::new();
    p.positions(lambda, &mut r);
    for (j, (c, (r, l))) in p.contacts.iter().zip(r.iter().zip(lambda)).enumerate() {
        let n = c.contact.normal;
        let (ln, lt) = (n.dot(l), (l - n * n.dot(l)).norm());
        assert!(n.dot(&(r - c.contact.point)) >= -1e-11, "contact {j} penetrates: {r}");
        assert!(
            ln >= 0.0 && lt <= c.contact.friction * ln * (1.0 + 1e-9) + 1e-12,
            "contact {j} outside its cone: {l}"
        );
    }
}

/// Two contacts on two vertices coupled strongly through `D`, plus a duplicate of the first
/// (a singular `D`): the solve converges to a point that every contact accepts.
#[test]
fn redundant_coupled_contacts_converge() {
    let y = Vector3::y();
    let contacts = [ground(0, y, 0.3), ground(1, y, 0.3), ground(0, y, 0.3)];
    // D of vertices 0, 1 (strongly coupled) with contact 2 = contact 0.
    let (a, b) = (1.0, 0.999);
    let d = [a, b, a, b, a, b, a, b, a];
    let f = [
        Vector3::new(0.05, -0.2, 0.0),
        Vector3::new(-0.02, -0.1, 0.0),
        Vector3::new(0.05, -0.2, 0.0),
    ];
    let p = problem(&contacts, &d, &f);
    let mut lambda = vec![Vector3::zeros(); 3];
    let mut space = ContactSpace::default();
    let out = space.solve(&p, &mut lambda, 1e-12, 2000, Effort::Full);
    assert!(out.converged, "{out:?}");
    assert!(ContactSpace::residual(&p, &lambda) <= 1e-12);
    assert_feasible(&p, &lambda);
}

/// The active set keeps `r = f + D lambda` by moving it along each Newton step; at the end
/// of an attempt it still equals a fresh product at the iterate reached (up to rounding).
#[test]
fn positions_kept_along_the_line_search_match_a_fresh_product() {
    let (contacts, d, f) = three_coupled();
    let p = problem(&contacts, &d, &f);
    let mut lambda = vec![Vector3::zeros(); 3];
    let mut space = ContactSpace::default();
    let (solved, solves) = space.active_set(&p, &mut lambda, 1e-13);
    assert!(solved && solves >= 1, "{solved} {solves}");
    let mut fresh = Vec::new();
    p.positions(&lambda, &mut fresh);
    for (kept, fresh) in space.r.iter().zip(&fresh) {
        assert!((kept - fresh).amax() <= 1e-14, "{kept} against {fresh}");
    }
    assert!(ContactSpace::residual(&p, &lambda) <= 1e-13);
}

/// Three contacts on almost the same relative coordinate with planes 40 degrees apart and
/// friction (a cloth vertex near a face corner, met by a vertex-face pair from each side):
/// the active-set method converges within a few sweeps to a point every contact accepts.
#[test]
fn near_duplicate_contacts_with_different_planes_converge_quickly() {
    let contacts = [
        ground(0, tilt(0.0), 0.1),
        ground(1, tilt(40.0), 0.1),
        ground(2, tilt(-20.0), 0.1),
    ];
    let (a, b) = (1.0, 0.998);
    let d = [a, b, b, b, a, b, b, b, a];
    let f = [
        Vector3::new(0.03, -0.2, 0.01),
        Vector3::new(0.031, -0.199, 0.01),
        Vector3::new(0.029, -0.201, 0.011),
    ];
    let p = problem(&contacts, &d, &f);
    let mut lambda = vec![Vector3::zeros(); 3];
    let out = ContactSpace::default().solve(&p, &mut lambda, 1e-12, 2000, Effort::Full);
    assert!(out.converged, "{out:?}");
    assert!(out.sweeps <= 10, "{out:?}");
    assert_feasible(&p, &lambda);
}

/// Sliding contacts coupled through `D`, started from zero so the states change over the
/// first Newton steps (when slip directions below DIRECTION_GAIN are held): the solve
/// reaches the same impulses as the method that linearizes every direction in every step,
/// and a point every contact accepts.
#[test]
fn holding_slip_directions_while_the_states_change_reaches_the_same_solution() {
    let contacts = [
        ground(0, tilt(0.0), 0.3),
        ground(1, tilt(10.0), 0.2),
        ground(2, tilt(-15.0), 0.4),
        ground(3, Vector3::y(), 0.1),
    ];
    #[rustfmt::skip]
    let d = [
        1.0, 0.3, 0.1, 0.05,
        0.3, 1.2, 0.2, 0.1,
        0.1, 0.2, 0.8, 0.3,
        0.05, 0.1, 0.3, 1.1,
    ];
    // Far along the tangents (sliding), some pushed into their planes, one pulled away.
    let f = [
        Vector3::new(0.9, -0.2, 0.4),
        Vector3::new(-0.5, -0.15, 0.8),
        Vector3::new(0.3, -0.3, -0.7),
        Vector3::new(-0.2, 0.4, 0.1),
    ];
    let p = problem(&contacts, &d, &f);
    let solve = |always_linearize: bool| {
        let mut space = ContactSpace {
            always_linearize,
            ..ContactSpace::default()
        };
        let mut lambda = vec![Vector3::zeros(); 4];
        let out = space.solve(&p, &mut lambda, 1e-13, 5000, Effort::Full);
        assert!(out.converged, "{out:?}");
        assert!(ContactSpace::residual(&p, &lambda) <= 1e-13);
        assert_feasible(&p, &lambda);
        lambda
    };
    let (held, linearized) = (solve(false), solve(true));
    for (a, b) in held.iter().zip(&linearized) {
        assert!((a - b).amax() <= 1e-9, "{a} against {b}");
    }
    // The problem does exercise sliding: some impulse has a tangential part.
    assert!(held
        .iter()
        .zip(&contacts)
        .any(|(l, c)| (l - c.contact.normal * c.contact.normal.dot(l)).norm() > 1e-3));
}

/// Contacts that ask the same vertex to be above and below a plane: no solution; the solve
/// says so (not converged, stalled) long before its cap.
#[test]
fn an_infeasible_set_stalls_instead_of_running_to_the_cap() {
    let (contacts, d, f) = above_and_below();
    let p = problem(&contacts, &d, &f);
    let mut lambda = vec![Vector3::zeros(); 2];
    let out = ContactSpace::default().solve(&p, &mut lambda, 1e-12, 100_000, Effort::Full);
    assert!(!out.converged && out.stalled, "{out:?}");
    assert!(out.sweeps < 2000, "{out:?}");
}

/// After a stall, a solve of the same set runs Gauss-Seidel only: on the infeasible set it
/// stops within AFTER_STALL_SWEEPS sweeps with no active-set solve (the full solve took
/// active-set attempts and hundreds of sweeps); on a solvable set started near its solution
/// it still reports converged, at the same solution the full solve reaches.
#[test]
fn a_solve_after_a_stall_runs_only_a_few_sweeps_and_still_converges_where_it_can() {
    let (contacts, d, f) = above_and_below();
    let p = problem(&contacts, &d, &f);
    let mut space = ContactSpace::default();
    let mut lambda = vec![Vector3::zeros(); 2];
    let full = space.solve(&p, &mut lambda, 1e-12, 100_000, Effort::Full);
    assert!(
        full.stalled && full.active_set_solves > 0 && full.sweeps > 200,
        "{full:?}"
    );
    let again = space.solve(&p, &mut lambda, 1e-12, 100_000, Effort::AfterStall);
    assert!(!again.converged, "{again:?}");
    assert!(
        again.sweeps <= AFTER_STALL_SWEEPS && again.active_set_solves == 0,
        "{again:?}"
    );

    let (contacts, d, f) = three_coupled();
    let p = problem(&contacts, &d, &f);
    let mut solved = vec![Vector3::zeros(); 3];
    assert!(space.solve(&p, &mut solved, 1e-13, 5000, Effort::Full).converged);
    let mut lambda: Vec<_> = solved.iter().map(|l| l * (1.0 + 1e-6)).collect();
    let out = space.solve(&p, &mut lambda, 1e-13, 5000, Effort::AfterStall);
    assert!(out.converged && out.active_set_solves == 0, "{out:?}");
    assert!(ContactSpace::residual(&p, &lambda) <= 1e-13);
    for (a, b) in lambda.iter().zip(&solved) {
        assert!((a - b).amax() <= 1e-10, "{a} against {b}");
    }
}
