//! The acceptance gate: whether a registered candidate is a loop safe to put in a pose graph.

use core::cmp::Ordering;
use core::fmt;

use super::{agreement, Hypothesis, Registration};
use crate::params::{field, Field, Kind, Params, FINITE};
use crate::Error;

/// Why [`Gate::check`] rejected a registration, in the order the checks run; from
/// `OdometryDisagrees` on they come from a loop detector's checks that follow the gate ([`crate::db::VerifyConfig`]).
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// The fine level did not converge.
    NotConverged,
    /// `fitness` (the smaller overlap) is below `min_fitness`.
    LowOverlap,
    /// `structure_fitness` is below `min_structure_fitness`.
    LowStructureOverlap,
    /// The inlier RMSE is above `max_rmse`.
    HighRmse,
    /// The translation is poorly constrained (a corridor, a single wall).
    DegenerateTranslation,
    /// The rotation is poorly constrained.
    DegenerateRotation,
    /// The translation is poorly constrained once the rotation is free: it can trade against a
    /// rotation (one wall turned onto another).
    WeakMarginalTranslation,
    /// Too few initial yaws reached the best pose.
    Disagreement,
    /// The two places are farther apart than `max_translation`.
    TooFar,
    /// The pose disagrees with the relative pose of the two places' poses beyond the
    /// odometry's drift bounds.
    OdometryDisagrees,
    /// Another candidate of the same step passed too and disagrees with this one through the
    /// poses: at most one of them is right.
    Ambiguous,
    /// Too few of the previous steps had a verified candidate that agrees with this loop.
    Unsupported,
    /// A look-alike of the candidate (a place far from it, as close to the query by its
    /// descriptor) lies where the loop's pose would put the query within the drift bounds too:
    /// the odometry cannot tell which place the query sees.
    LookAlike,
    /// A loop into another session's map before the session is placed in it, or a loop within
    /// the session across a break of its odometry before the loops across that break place one
    /// side on the other: too few of those loops agree with each other yet (the detector's
    /// `placement_loops` over `placement_m` metres).
    NotPlaced,
    /// A loop into another session's map that disagrees with the session's placement in it.
    OffPlacement,
    /// The candidate's stored cloud is corrupt (its checksum fails) or could not be read from
    /// the map's file: it was not registered.
    CorruptCloud,
}

impl fmt::Display for Rejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Rejection::NotConverged => "not converged",
            Rejection::LowOverlap => "low overlap",
            Rejection::LowStructureOverlap => "low structure overlap",
            Rejection::HighRmse => "high rmse",
            Rejection::DegenerateTranslation => "degenerate translation",
            Rejection::DegenerateRotation => "degenerate rotation",
            Rejection::WeakMarginalTranslation => "translation trades against rotation",
            Rejection::Disagreement => "hypotheses disagree",
            Rejection::TooFar => "too far apart",
            Rejection::OdometryDisagrees => "disagrees with the odometry",
            Rejection::Ambiguous => "another candidate disagrees",
            Rejection::Unsupported => "not supported by the previous steps",
            Rejection::LookAlike => "a look-alike the odometry cannot rule out",
            Rejection::NotPlaced => {
                "not placed yet: too few loops into the map (or across a break of the odometry) agree with each other"
            }
            Rejection::OffPlacement => "disagrees with the session's placement in the map",
            Rejection::CorruptCloud => "its stored cloud is corrupt or unreadable",
        })
    }
}

/// Thresholds that a registration must meet to be accepted as a loop. Tuned for precision: a
/// wrong loop in a pose graph costs far more than a missed one. The defaults come from measured
/// distributions (see [`Gate::default`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gate {
    /// Require [`Registration::converged`].
    pub require_converged: bool,
    /// Smallest accepted [`Registration::fitness`] (the smaller of the two overlaps).
    pub min_fitness: f64,
    /// Smallest accepted [`Registration::structure_fitness`].
    pub min_structure_fitness: f64,
    /// Largest accepted [`Registration::rmse`] (metres).
    pub max_rmse: f64,
    /// Smallest accepted [`super::Degeneracy::translation`].
    pub min_translation_information: f64,
    /// Smallest accepted [`super::Degeneracy::rotation`].
    pub min_rotation_information: f64,
    /// Smallest accepted [`super::Degeneracy::marginal_translation`]: the translation's
    /// information with the rotation marginalised, per correspondence.
    pub min_marginal_translation_information: f64,
    /// Fewest hypotheses (the best included) that must reach the best pose, when hypotheses
    /// are given.
    pub min_agreement: usize,
    /// Largest accepted length of the translation (metres). Infinite by default: a loop
    /// between places 6 m apart is as good a constraint as any; an evaluation that counts a loop
    /// as correct only within a radius (SPEC §5) sets this to the radius.
    pub max_translation: f64,
    /// Two hypotheses agree when their poses are within this distance (metres) ...
    pub agree_translation: f64,
    /// ... and this angle (degrees).
    pub agree_rotation_deg: f64,
}

impl Default for Gate {
    /// Thresholds from the measured distributions of correct and wrong registrations
    /// (`tools/reg_measure.py`, `tools/reg_schedule.py information`; figures in
    /// docs/performance.md#gate), tuned so that no wrong one passes.
    fn default() -> Self {
        Gate {
            require_converged: false,
            min_fitness: 0.35,
            min_structure_fitness: 0.35,
            max_rmse: 0.30,
            min_translation_information: 1.5,
            min_rotation_information: 0.0,
            min_marginal_translation_information: 1.2,
            min_agreement: 1,
            max_translation: f64::INFINITY,
            agree_translation: 0.5,
            agree_rotation_deg: 2.0,
        }
    }
}

/// `v >= min`, false when either is NaN (a NaN measure or threshold never passes).
fn at_least(v: f64, min: f64) -> bool {
    matches!(
        v.partial_cmp(&min),
        Some(Ordering::Greater | Ordering::Equal)
    )
}

impl Gate {
    /// `Ok(())` when `reg` passes every threshold, else the first failed check. `hypotheses`
    /// are the outcomes of [`super::register_hypotheses`] with the index of the best, or empty
    /// (then agreement is not checked).
    ///
    /// # Errors
    /// The [`Rejection`] of the first failed check.
    pub fn check(
        &self,
        reg: &Registration,
        hypotheses: &[Hypothesis],
        best: usize,
    ) -> Result<(), Rejection> {
        if self.require_converged && !reg.converged {
            return Err(Rejection::NotConverged);
        }
        if !at_least(reg.fitness, self.min_fitness) {
            return Err(Rejection::LowOverlap);
        }
        if !at_least(reg.structure_fitness, self.min_structure_fitness) {
            return Err(Rejection::LowStructureOverlap);
        }
        if !at_least(self.max_rmse, reg.rmse) {
            return Err(Rejection::HighRmse);
        }
        if !at_least(reg.degeneracy.translation, self.min_translation_information) {
            return Err(Rejection::DegenerateTranslation);
        }
        if !at_least(reg.degeneracy.rotation, self.min_rotation_information) {
            return Err(Rejection::DegenerateRotation);
        }
        if !at_least(
            reg.degeneracy.marginal_translation,
            self.min_marginal_translation_information,
        ) {
            return Err(Rejection::WeakMarginalTranslation);
        }
        if !hypotheses.is_empty() && self.agreement(hypotheses, best) < self.min_agreement {
            return Err(Rejection::Disagreement);
        }
        let t = reg.translation();
        if !at_least(
            self.max_translation,
            libm::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]),
        ) {
            return Err(Rejection::TooFar);
        }
        Ok(())
    }

    /// How many `hypotheses` reached `hypotheses[best]`'s pose within this gate's tolerances.
    pub fn agreement(&self, hypotheses: &[Hypothesis], best: usize) -> usize {
        agreement(
            hypotheses,
            best,
            self.agree_translation,
            self.agree_rotation_deg,
        )
    }
}

/// A finite threshold.
const NUMBER: Kind = Kind::closed(-FINITE, FINITE);

impl Gate {
    /// Checks every threshold against its range in [`Gate::FIELDS`].
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first invalid one.
    pub fn validate(&self) -> Result<(), Error> {
        self.check_fields()
    }
}

impl Params for Gate {
    const NAME: &'static str = "AcceptanceGate";
    const FIELDS: &'static [Field<Gate>] = &[
        field!(
            Gate,
            "require_converged",
            require_converged,
            Kind::Bool,
            "a bool",
            "Require the fine level to have converged."
        ),
        field!(
            Gate,
            "min_fitness",
            min_fitness,
            NUMBER,
            "a finite number",
            "Smallest accepted fitness (the smaller of the two overlaps)."
        ),
        field!(
            Gate,
            "min_structure_fitness",
            min_structure_fitness,
            NUMBER,
            "a finite number",
            "Smallest accepted overlap of the structure (points off the ground)."
        ),
        field!(
            Gate,
            "max_rmse",
            max_rmse,
            NUMBER,
            "a finite number",
            "Largest accepted inlier RMSE, metres."
        ),
        field!(
            Gate,
            "min_translation_information",
            min_translation_information,
            NUMBER,
            "a finite number",
            "Smallest accepted translation information (degeneracy.translation)."
        ),
        field!(
            Gate,
            "min_rotation_information",
            min_rotation_information,
            NUMBER,
            "a finite number",
            "Smallest accepted rotation information (degeneracy.rotation)."
        ),
        field!(
            Gate,
            "min_marginal_translation_information",
            min_marginal_translation_information,
            NUMBER,
            "a finite number",
            "Smallest accepted translation information with the rotation marginalised, per correspondence (degeneracy.marginal_translation)."
        ),
        field!(
            Gate,
            "min_agreement",
            min_agreement,
            Kind::at_least(0),
            "an integer >= 0",
            "Fewest initial yaws (the best included) that must reach the best pose."
        ),
        field!(
            Gate,
            "max_translation",
            max_translation,
            Kind::open_closed(0.0, f64::INFINITY),
            "metres > 0 (infinity: no limit)",
            "Largest accepted length of the translation, metres."
        ),
        field!(
            Gate,
            "agree_translation",
            agree_translation,
            NUMBER,
            "a finite number",
            "Two hypotheses agree when their translations differ by at most this, metres (and their rotations by agree_rotation_deg)."
        ),
        field!(
            Gate,
            "agree_rotation_deg",
            agree_rotation_deg,
            NUMBER,
            "a finite number",
            "Two hypotheses agree when their rotations differ by at most this, degrees (and their translations by agree_translation)."
        ),
    ];

    fn defaults() -> Gate {
        Gate::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reg::Degeneracy;

    /// A registration that passes every default threshold, with the given marginal information.
    fn registration(marginal_translation: f64) -> Registration {
        Registration {
            fitness: 0.8,
            structure_fitness: 0.8,
            rmse: 0.1,
            converged: true,
            degeneracy: Degeneracy {
                rotation: 50.0,
                translation: 5.0,
                marginal_translation,
            },
            ..Registration::default()
        }
    }

    #[test]
    fn the_marginal_translation_term_rejects_below_its_threshold_only() {
        let gate = Gate {
            min_marginal_translation_information: 1.0,
            ..Gate::default()
        };
        assert_eq!(gate.check(&registration(1.0), &[], 0), Ok(()));
        assert_eq!(gate.check(&registration(3.0), &[], 0), Ok(()));
        for weak in [0.99, 0.0, f64::NAN] {
            assert_eq!(
                gate.check(&registration(weak), &[], 0),
                Err(Rejection::WeakMarginalTranslation),
                "{weak}"
            );
        }
        // Off (0), a weak marginal passes; the block's own term still comes first.
        let off = Gate {
            min_marginal_translation_information: 0.0,
            ..gate
        };
        assert_eq!(off.check(&registration(0.0), &[], 0), Ok(()));
        let mut r = registration(0.0);
        r.degeneracy.translation = 0.5;
        assert_eq!(
            gate.check(&r, &[], 0),
            Err(Rejection::DegenerateTranslation)
        );
    }

    #[test]
    fn the_marginal_translation_threshold_is_a_table_parameter() {
        let mut gate = Gate::default();
        let f = Gate::field("min_marginal_translation_information").unwrap();
        f.set(&mut gate, crate::params::Value::Float(0.7)).unwrap();
        assert_eq!(gate.min_marginal_translation_information, 0.7);
        assert!(f
            .set(&mut gate, crate::params::Value::Float(f64::NAN))
            .is_err());
        assert_eq!(
            Rejection::WeakMarginalTranslation.to_string(),
            "translation trades against rotation"
        );
    }
}
