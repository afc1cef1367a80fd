//! The cycles: constraints and materials handed to the one multigrid hierarchy, the
//! corotated implant stage with its line search, the linear gravity correction, and the
//! solve to a tolerance.

use super::*;

impl Simulation {
    pub(super) fn constraints_changed(&mut self) {
        self.gravity_guess = self.gravity_correction();
        if let StageState::Gravity(gravity) =
            std::mem::replace(&mut self.stage, StageState::Implant)
        {
            // back to stage 1's hierarchy, whose constraints `dirty` renews
            self.multigrid = Some(gravity.multigrid);
        }
        self.f_ext.clear();
        self.stage_cycles = 0;
        self.dirty = true;
        self.fresh = true;
        self.stage_one_search = false;
        self.stage_one_residuals.clear();
        self.newton_krylov = false;
        self.warmup_left = 0;
        self.released = false;
    }

    /// The constraints of `stage`: stage 1's hold the implant vertices where the template
    /// puts them (once released as a gel, only those on the band), stage 2's release
    /// them.
    ///
    /// Besides the wall and the templates, a free vertex all of whose neighbours are held
    /// at zero is held at zero too (repeatedly): in stage 1 its equilibrium displacement
    /// is zero anyway (no load acts on it; a released gel's vertices are never taken for
    /// such, its elements push), and such islands, found between the fixed back vertices
    /// and the posterior wall, leave coarse multigrid functions that only see one free
    /// fine vertex, which made the Galerkin coarse operator singular.
    pub(super) fn constraints(&self, stage: Stage) -> Constraints {
        let with_implant_vertices = stage == Stage::Implant && !self.released;
        let n = self.finest.positions.len();
        let mut zero = vec![false; n];
        let mut held = vec![false; n];
        for &v in &self.wall {
            zero[v as usize] = true;
        }
        for implant in self.implants.iter().flatten() {
            for &v in implant
                .template
                .fixed_vertices
                .iter()
                .chain(&implant.fold_vertices)
            {
                zero[v as usize] = true;
            }
        }
        if stage == Stage::Implant {
            for implant in self.implants.iter().flatten() {
                for &(v, _) in &implant.template.implant_vertices {
                    held[v as usize] = true;
                    zero[v as usize] = false;
                }
            }
        }
        let mut islands = Vec::new();
        loop {
            let before = islands.len();
            for v in 0..n {
                if zero[v] || held[v] {
                    continue;
                }
                let nb = &self.neighbours[self.neighbour_ptr[v]..self.neighbour_ptr[v + 1]];
                if !nb.is_empty() && nb.iter().all(|&w| zero[w as usize]) {
                    zero[v] = true;
                    islands.push(v as u32);
                }
            }
            if islands.len() == before {
                break;
            }
        }
        let mut c = Constraints::new();
        for &v in &self.wall {
            c.fix(v);
        }
        for &v in &islands {
            c.fix(v);
        }
        for implant in self.implants.iter().flatten() {
            for &v in implant
                .template
                .fixed_vertices
                .iter()
                .chain(&implant.fold_vertices)
            {
                c.fix(v);
            }
            for &(v, d) in &implant.template.implant_vertices {
                if with_implant_vertices {
                    c.prescribe(v, d);
                } else if self.on_band[v as usize] && stage == Stage::Implant {
                    // a released gel's vertex on the band stays where the template put it
                    c.prescribe(v, d);
                } else if self.on_band[v as usize] {
                    // where the model is cut through the body, the holding force includes
                    // the unmodelled tissue's: released, the vertex would hang on the soft
                    // implant elements alone, so it keeps its stage-1 place
                    c.fix(v);
                }
            }
        }
        c
    }

    /// The finest model with the implant elements' soft material.
    pub(super) fn finest_model(&self) -> Result<FemModel, SimulationError> {
        let mut model = self.levels[0].clone();
        let soft = self.options.soft_implant();
        for implant in self.implants.iter().flatten() {
            for &e in &implant.template.implant_elements {
                model.set_material(e as usize, soft)?;
            }
        }
        Ok(model)
    }

    /// A multigrid over the hierarchy with the posterior wall as its permanent
    /// constraints and `finest` set as the changeable ones.
    pub(super) fn build_multigrid(
        &self,
        finest: Constraints,
        tangent: Tangent,
    ) -> Result<Multigrid, SimulationError> {
        let mut levels = Vec::with_capacity(self.levels.len());
        let mut wall = Constraints::new();
        for &v in &self.wall {
            wall.fix(v);
        }
        levels.push((self.finest_model()?, wall));
        let galerkin = self.coarse_operator == CoarseOperator::Galerkin;
        for (m, wall) in self.levels[1..].iter().zip(&self.coarse_walls) {
            let mut c = Constraints::new();
            if !galerkin {
                for &v in wall {
                    c.fix(v);
                }
            }
            levels.push((m.clone(), c));
        }
        let options = MultigridOptions {
            coarse_operator: self.coarse_operator,
            tangent,
            ..self.options.multigrid
        };
        let mut mg = Multigrid::with_permanent_constraints(levels, options)?;
        mg.set_constraints(&finest)?;
        Ok(mg)
    }

    /// Gives a stage's finest model the current implants' soft elements, or once they
    /// are released the gel's elements with its material and the template's shape as
    /// their rest shape (and the tissue or muscle with the mesh's shape back to the
    /// elements of earlier implants) and, in stage 1, the sliders
    /// that keep the skin over a thin pocket at the template's distance (stage 2 has
    /// none: their stage-1 forces become dead loads there).
    pub(super) fn update_implant_model(
        &self,
        stage: &mut StageMultigrid,
        which: Stage,
    ) -> Result<(), SimulationError> {
        let soft = self.options.soft_implant();
        let gel = self.options.implant_gel.filter(|_| self.released);
        let current = self.implant_elements();
        for &e in &stage.soft_elements {
            let own = self.levels[0].materials()[e as usize];
            stage.multigrid.set_material(e as usize, own)?;
            stage.multigrid.set_rest_shape(e as usize, None)?;
        }
        let target = gel.map(|_| self.template_positions());
        for &e in &current {
            let shape = target.as_ref().and_then(|target| {
                let t = self.finest.tets[e as usize];
                Some((gel?, t.map(|v| target[v as usize])))
            });
            let Some((gel, corners)) = shape else {
                stage.multigrid.set_material(e as usize, soft)?;
                continue;
            };
            stage.multigrid.set_material(e as usize, gel)?;
            // an element the template turns over (squeezed at the rim) has no shape to
            // keep: it stays a soft filler
            if stage
                .multigrid
                .set_rest_shape(e as usize, Some(corners))
                .is_err()
            {
                stage.multigrid.set_material(e as usize, soft)?;
            }
        }
        stage.soft_elements = current;
        let sliders = match which {
            Stage::Implant => self.skin_sliders(),
            Stage::Gravity => Vec::new(),
        };
        stage.multigrid.set_sliders(&sliders)?;
        Ok(())
    }

    /// One [`fem::Slider`] per skin vertex the templates would push
    /// ([`ImplantTemplate::skin_vertices`]): on the plane through its template
    /// displacement across the bed's normal, so the skin keeps its distance from the
    /// implant and slides over it. A vertex in both sides' templates keeps the first
    /// side's.
    fn skin_sliders(&self) -> Vec<Slider> {
        let stiffness_mn_per_mm =
            SKIN_SLIDER_STIFFNESS_MULTIPLE * self.options.tissue.young_kpa * self.spacing_mm;
        let mut seen = vec![false; self.u.len()];
        (self.implants.iter().flatten())
            .flat_map(|implant| &implant.template.skin_vertices)
            .filter(|&&(vertex, _)| !std::mem::replace(&mut seen[vertex as usize], true))
            .map(|&(vertex, displacement)| Slider {
                vertex,
                displacement,
                normal: displacement,
                stiffness_mn_per_mm,
            })
            .collect()
    }

    /// How many multigrid hierarchies the session has built: one at its first cycle (or
    /// at the first start of the gravity correction, if that comes first), and again
    /// after a switch of coarse operator ([`Simulation::coarse_fallbacks`]).
    pub fn multigrid_builds(&self) -> usize {
        self.multigrid_builds
    }

    /// How often a Galerkin coarse operator turned out singular and the session switched
    /// to rediscretised coarse operators (at most once per session), and the operator in
    /// use.
    pub fn coarse_fallbacks(&self) -> (usize, CoarseOperator) {
        (self.coarse_fallbacks, self.coarse_operator)
    }

    /// Stage 1's hierarchy, taken out of the session, up to date with the current
    /// constraints; and whether it had to be built. The caller puts it back.
    pub(super) fn take_stage_one_multigrid(
        &mut self,
    ) -> Result<(StageMultigrid, bool), SimulationError> {
        match self.multigrid.take() {
            Some(kept) if !self.dirty => Ok((kept, false)),
            taken => {
                self.multigrid = taken;
                let prepared = self.prepared_multigrid(Stage::Implant)?;
                self.dirty = false;
                Ok(prepared)
            }
        }
    }

    /// The session's hierarchy, taken out of it, with the constraints, tangent and
    /// implant materials of `stage`, built if there is none yet; and whether it was
    /// built. A new implant or position changes the constrained set: the kept hierarchy
    /// keeps its patterns and only swaps the changeable constraints (fem's symmetric
    /// elimination over a fixed pattern) and the tangent it assembles.
    pub(super) fn prepared_multigrid(
        &mut self,
        stage: Stage,
    ) -> Result<(StageMultigrid, bool), SimulationError> {
        let (constraints, tangent) = match stage {
            Stage::Implant => (self.constraints(stage), self.options.multigrid.tangent),
            Stage::Gravity => (self.constraints(stage), self.options.gravity_tangent),
        };
        let (mut kept, built) = match self.multigrid.take() {
            Some(mut kept) => {
                kept.multigrid.set_constraints(&constraints)?;
                kept.multigrid.set_tangent(tangent);
                (kept, false)
            }
            None => {
                let kept = StageMultigrid {
                    multigrid: self.build_multigrid(constraints, tangent)?,
                    soft_elements: Vec::new(),
                };
                self.multigrid_builds += 1;
                (kept, true)
            }
        };
        self.update_implant_model(&mut kept, stage)?;
        Ok((kept, built))
    }

    /// The current stage's multigrid, once built.
    pub(super) fn stage_multigrid(&self) -> Option<&Multigrid> {
        match &self.stage {
            StageState::Implant => self.multigrid.as_ref().map(|kept| &kept.multigrid),
            StageState::Gravity(gravity) => Some(&gravity.multigrid.multigrid),
        }
    }

    /// One interactive step: rotation update, reassembly (or, near stage 1's answer, the
    /// forces alone on kept operators, [`SimulationOptions::lagged_operators`]) and one
    /// V(2,1)-cycle of the current stage (a Newton-Krylov step in a stalled stage 1, one
    /// preconditioned
    /// conjugate gradient iteration in stage 2), warm-started from the current
    /// displacement (giving stage 1's multigrid the new constraints first if they
    /// changed, building it at the session's first cycle).
    pub fn cycle(&mut self) -> Result<CycleInfo, SimulationError> {
        if self.stage() == Stage::Implant && self.fresh && self.u.iter().all(|d| *d == DVec3::ZERO)
        {
            self.warmup_left = self.options.linear_warmup_cycles;
        }
        if self.warmup_left > 0 {
            self.warmup_left -= 1;
            let info = self.cycle_with(Formulation::Linear)?;
            if info.relative_residual < WARMUP_TOLERANCE {
                self.warmup_left = 0;
            }
            // the first corotated cycle starts afresh (no line search, energy unknown)
            self.fresh = self.warmup_left == 0 || self.fresh;
            return Ok(info);
        }
        self.cycle_with(Formulation::Corotated)
    }

    /// [`Simulation::cycle`] with a chosen formulation (the linear one as a warm-up).
    pub fn cycle_with(&mut self, formulation: Formulation) -> Result<CycleInfo, SimulationError> {
        let u_before = self.u.clone();
        match self.cycle_once(formulation) {
            Err(SimulationError::Fem(fem::FemError::Singular { .. }))
                if self.coarse_operator == CoarseOperator::Galerkin && self.levels.len() > 1 =>
            {
                // a singular Galerkin coarse operator: rediscretised levels from now on
                self.coarse_operator = CoarseOperator::Rediscretised;
                self.coarse_fallbacks += 1;
                self.u = u_before;
                self.rebuild_current_stage()?;
                self.cycle_once(formulation)
            }
            other => other,
        }
    }

    /// Rebuilds the multigrid for the current stage after a change of coarse operator.
    pub(super) fn rebuild_current_stage(&mut self) -> Result<(), SimulationError> {
        self.multigrid = None;
        match std::mem::replace(&mut self.stage, StageState::Implant) {
            StageState::Implant => self.dirty = true,
            StageState::Gravity(gravity) => self.enter_gravity_stage(gravity.u_implant)?,
        }
        Ok(())
    }

    pub(super) fn cycle_once(
        &mut self,
        formulation: Formulation,
    ) -> Result<CycleInfo, SimulationError> {
        let start = Instant::now();
        if let StageState::Gravity(gravity) = &mut self.stage {
            let (residual_mn, relative_residual) = gravity.cycle(&mut self.u);
            self.last_energy = None;
            self.last_step = 1.0;
            self.fresh = false;
            self.last_relative_residual = relative_residual;
            self.stage_cycles += 1;
            return Ok(CycleInfo {
                stage: Stage::Gravity,
                residual_mn,
                relative_residual,
                rebuilt: false,
                step: 1.0,
                linear: false,
                newton_krylov: false,
                lagged: false,
                time_ms: elapsed_ms(start),
            });
        }
        let (kept, rebuilt) = self.take_stage_one_multigrid()?;
        let fresh = std::mem::take(&mut self.fresh) || rebuilt;
        let search = self.options.line_search
            && self.stage_one_search
            && !fresh
            && formulation == Formulation::Corotated;
        let u_old = search.then(|| self.u.clone());
        let newton_krylov = self.newton_krylov && formulation == Formulation::Corotated;
        let (tangent, krylov_iterations) = if newton_krylov {
            (Tangent::Full, self.options.newton_krylov_iterations)
        } else {
            (
                self.options.multigrid.tangent,
                self.options.multigrid.krylov_iterations,
            )
        };
        let lag = !fresh && !newton_krylov && self.lags(formulation);
        let mg = &mut self.multigrid.insert(kept).multigrid;
        mg.set_tangent(tangent);
        mg.set_krylov_iterations(krylov_iterations);
        let report = if lag {
            let start = self.u.clone();
            // only while the residual keeps falling
            let limit = self.last_residual_mn;
            let report = mg.lagged_cycle(&mut self.u, &self.f_ext, formulation, limit)?;
            if report.operators_lagged {
                self.anderson.mix(&start, &mut self.u);
            }
            report
        } else {
            mg.cycle(&mut self.u, &self.f_ext, formulation)?
        };
        if !report.operators_lagged {
            // a new map: the steps of the old one do not mix with its
            self.anderson.clear();
        }
        if let Some(u_old) = u_old {
            // backtracking on the potential energy (the corotated forces are conservative)
            let model = mg.model();
            let energy = |u: &[DVec3]| model.potential_energy(u, &self.f_ext, formulation);
            let e0 = match self.last_energy {
                Some(e) => e,
                None => energy(&u_old),
            };
            let step: Vec<DVec3> = self.u.iter().zip(&u_old).map(|(a, b)| *a - *b).collect();
            let mut alpha = 1.0;
            let mut e = energy(&self.u);
            let mut halvings = 0;
            while (e > e0 || e.is_nan()) && halvings < MAX_HALVINGS {
                alpha *= 0.5;
                halvings += 1;
                for ((u, o), d) in self.u.iter_mut().zip(&u_old).zip(&step) {
                    *u = *o + *d * alpha;
                }
                e = energy(&self.u);
            }
            self.last_energy = Some(e);
            self.last_step = alpha;
        } else {
            self.last_energy = None;
            self.last_step = 1.0;
        }
        // relative to the reaction forces at the held vertices (from this cycle's
        // assembly) plus the external loads
        let reaction = mg.system().reaction_norm_squared();
        let external: f64 = self.f_ext.iter().map(|x| x.length_squared()).sum();
        let relative = report.residual_before / (reaction + external).sqrt().max(1e-12);
        if !fresh && formulation == Formulation::Corotated && relative > self.last_relative_residual
        {
            self.stage_one_search = true;
        }
        self.last_relative_residual = relative;
        self.last_residual_mn = report.residual_before;
        // the residual before a fresh cycle is the change's, not the iteration's: the
        // window starts after it
        if formulation == Formulation::Corotated && !fresh {
            if self.stage_one_residuals.len() > STALL_WINDOW {
                self.stage_one_residuals.remove(0);
            }
            self.stage_one_residuals.push(relative);
            let cycle_cost = if self.lags(formulation) {
                LAGGED_CYCLE_COST
            } else {
                1.0
            };
            self.newton_krylov |= self.options.newton_krylov_iterations > 0
                && stalled(&self.stage_one_residuals)
                && newton_krylov_pays(&self.stage_one_residuals, self.aimed_tolerance, cycle_cost);
        }
        self.stage_cycles += 1;
        Ok(CycleInfo {
            stage: Stage::Implant,
            residual_mn: report.residual_before,
            relative_residual: relative,
            rebuilt,
            step: self.last_step,
            linear: formulation == Formulation::Linear,
            newton_krylov,
            lagged: report.operators_lagged,
            time_ms: elapsed_ms(start),
        })
    }

    /// Whether stage 1's next warped cycle (not the first after a change) keeps the
    /// operators: [`SimulationOptions::lagged_operators`] on, and the residual before
    /// the last corotated cycle below [`LAGGED_OPERATORS_BELOW`] and below the one
    /// before it (`lagged_cycle`'s limit then also asks the residual at the cycle's
    /// start to be below the last).
    fn lags(&self, formulation: Formulation) -> bool {
        let falling_below = match self.stage_one_residuals[..] {
            [.., before, last] => last < before && last < LAGGED_OPERATORS_BELOW,
            _ => false,
        };
        self.options.lagged_operators && formulation == Formulation::Corotated && falling_below
    }

    /// Cycles the current stage until the relative residual before a cycle is below
    /// `relative_tolerance` (that cycle is still run) or `max_cycles` were run.
    pub fn solve(
        &mut self,
        max_cycles: usize,
        relative_tolerance: f64,
    ) -> Result<SolveReport, SimulationError> {
        let start = Instant::now();
        let aimed_before = std::mem::replace(&mut self.aimed_tolerance, relative_tolerance);
        let cycled = self.cycle_until(max_cycles, relative_tolerance);
        self.aimed_tolerance = aimed_before;
        let (cycles, relative) = cycled?;
        Ok(SolveReport {
            stage: self.stage(),
            cycles,
            relative_residual: relative,
            converged: relative < relative_tolerance,
            time_ms: elapsed_ms(start),
        })
    }

    /// [`Simulation::solve`]'s loop: the cycles run and the last relative residual.
    fn cycle_until(
        &mut self,
        max_cycles: usize,
        relative_tolerance: f64,
    ) -> Result<(usize, f64), SimulationError> {
        let mut relative = f64::INFINITY;
        for cycles in 1..=max_cycles {
            let info = self.cycle()?;
            relative = info.relative_residual;
            if relative < relative_tolerance && !info.linear {
                return Ok((cycles, relative));
            }
        }
        Ok((max_cycles, relative))
    }

    /// Switches to stage 2 (paper V-B) from the current (stage-1) displacement: the
    /// implant vertices' holding forces and the added implant weight become loads, the
    /// implant vertices are released. Does nothing without implants or when already
    /// there. The session's multigrid only swaps its constraints and tangent (see the
    /// module documentation). Run
    /// [`Simulation::cycle`] or [`Simulation::solve`] afterwards.
    pub fn start_gravity_correction(&mut self) -> Result<(), SimulationError> {
        if self.stage() == Stage::Gravity || self.implants.iter().all(Option::is_none) {
            return Ok(());
        }
        let mut f_ext = vec![DVec3::ZERO; self.u.len()];
        let g = -self.frame.up()
            * (self.options.gravity_m_s2
                * self.options.implant_density_kg_m3
                * fem::model::KG_M3_TIMES_M_S2_TO_MN_MM3);
        for implant in self.implants.iter().flatten() {
            let template = &implant.template;
            for &e in template
                .implant_elements
                .iter()
                .chain(&template.sliding_elements)
            {
                let t = self.finest.tets[e as usize];
                let p = t.map(|v| self.finest.positions[v as usize]);
                let q = [0, 1, 2, 3].map(|k| p[k] + self.u[t[k] as usize]);
                let added = tetra::quality::signed_volume(q) - tetra::quality::signed_volume(p);
                for &v in &t {
                    f_ext[v as usize] += g * (added * 0.25);
                }
            }
        }
        self.f_ext = f_ext;
        if let Err(e) = self.enter_gravity_stage(self.u.clone()) {
            // still stage 1, whose loads are none
            self.f_ext.clear();
            return Err(e);
        }
        self.stage_cycles = 0;
        self.fresh = true;
        Ok(())
    }

    /// The vertices stage 2 loads with the force that held them in stage 1: the implant
    /// vertices (those stage 2 still holds, on the wall or the band, are not unknowns
    /// or are eliminated, and the system leaves them alone) and the skin on sliders.
    fn dead_load_vertices(&self) -> Vec<bool> {
        let mut marked = vec![false; self.u.len()];
        for implant in self.implants.iter().flatten() {
            if self.released {
                // a released gel's vertices are free in stage 1 already; the skin on
                // sliders is not
                for &(v, _) in &implant.template.skin_vertices {
                    marked[v as usize] = true;
                }
                continue;
            }
            for &(v, _) in implant.template.pushed_vertices() {
                marked[v as usize] = true;
            }
        }
        marked
    }

    /// Gives the hierarchy stage 2's constraints and tangent and assembles stage 2's
    /// linear system at stage 1's displacement `u_implant` under the current loads.
    fn enter_gravity_stage(&mut self, u_implant: Vec<DVec3>) -> Result<(), SimulationError> {
        let (mut kept, _) = self.prepared_multigrid(Stage::Gravity)?;
        let mg = &mut kept.multigrid;
        let assembled = mg
            .assemble(&u_implant, &self.f_ext, Formulation::Corotated)
            // the implant vertices' dead load is their internal force at `u_implant`
            .and_then(|()| {
                mg.internal_forces_as_dead_loads(&self.dead_load_vertices(), &self.f_ext)
            });
        if let Err(e) = assembled {
            // the hierarchy stays the session's, for stage 1 to take up again
            self.multigrid = Some(kept);
            self.dirty = true;
            return Err(e.into());
        }
        let rhs = mg.system().rhs.clone();
        let rhs_norm_mn = rhs.iter().map(|d| d.length_squared()).sum::<f64>().sqrt();
        let iteration = match &self.gravity_guess {
            Some(correction) => {
                let sys = mg.system();
                let guess = sys
                    .free
                    .iter()
                    .zip(sys.eliminated())
                    .map(|(&v, &held)| {
                        if held {
                            DVec3::ZERO
                        } else {
                            correction[v as usize]
                        }
                    })
                    .collect();
                PcgIteration::from_guess(mg, &rhs, guess)
            }
            None => PcgIteration::new(mg, &rhs, vec![DVec3::ZERO; rhs.len()]),
        };
        self.stage = StageState::Gravity(Box::new(GravityStage {
            multigrid: kept,
            u_implant,
            iteration,
            rhs_norm_mn,
        }));
        Ok(())
    }

    /// Every finest vertex where the current templates put it: rest position plus its
    /// prescribed displacement (the implants' shapes, stress-free for a released gel).
    fn template_positions(&self) -> Vec<DVec3> {
        let mut target = self.finest.positions.clone();
        for implant in self.implants.iter().flatten() {
            for &(v, d) in &implant.template.implant_vertices {
                target[v as usize] += d;
            }
        }
        target
    }

    /// The elements that are implant now: the templates' implant elements, or once
    /// released as a gel, the gel's ([`Simulation::gel_elements`]).
    pub fn implant_elements(&self) -> Vec<u32> {
        if self.options.implant_gel.is_some() && self.released {
            return self.gel_elements();
        }
        (self.implants.iter().flatten())
            .flat_map(|i| i.template.implant_elements.iter().copied())
            .collect()
    }

    /// The elements a released gel takes: the templates' implant elements and every
    /// finest element whose four corners the templates move or hold (the tissue layer
    /// they carry with the implant), so that a gel far stiffer than the tissue keeps the
    /// template's answer.
    fn gel_elements(&self) -> Vec<u32> {
        let mut prescribed = vec![false; self.finest.positions.len()];
        for implant in self.implants.iter().flatten() {
            let template = &implant.template;
            for &(v, _) in &template.implant_vertices {
                prescribed[v as usize] = true;
            }
            for &v in &template.fixed_vertices {
                prescribed[v as usize] = true;
            }
        }
        let mut elements: Vec<u32> = (self.finest.tets.iter().enumerate())
            .filter(|(_, t)| t.iter().all(|&v| prescribed[v as usize]))
            .map(|(e, _)| e as u32)
            .collect();
        // the template's own implant elements too, also where a corner is left free
        elements.extend(
            (self.implants.iter().flatten()).flat_map(|i| i.template.implant_elements.iter()),
        );
        elements.sort_unstable();
        elements.dedup();
        elements
    }

    /// Releases stage 1's implants as a gel ([`SimulationOptions::implant_gel`]) from
    /// the current displacement; the next cycles solve for where the tissue lets it be.
    fn release_implants(&mut self) {
        self.released = true;
        self.dirty = true;
        self.fresh = true;
        self.stage_cycles = 0;
        self.stage_one_search = false;
        self.stage_one_residuals.clear();
        self.newton_krylov = false;
    }

    /// Solves stage 1 to convergence and, unless `no_gravity`, the gravity correction,
    /// with the options' cycle limit and tolerance.
    pub fn run(&mut self, no_gravity: bool) -> Result<RunReport, SimulationError> {
        if self.stage() == Stage::Gravity {
            // start from the Dirichlet problem again
            self.constraints_changed();
        }
        let (max, tol) = (self.options.max_cycles, self.options.relative_tolerance);
        let mut implant = self.solve(max, tol)?;
        if self.options.implant_gel.is_some() && self.implants.iter().any(Option::is_some) {
            self.release_implants();
            let released = self.solve(max, tol)?;
            implant = SolveReport {
                cycles: implant.cycles + released.cycles,
                time_ms: implant.time_ms + released.time_ms,
                ..released
            };
        }
        let gravity = if no_gravity || self.implants.iter().all(Option::is_none) {
            None
        } else {
            self.start_gravity_correction()?;
            Some(self.solve(max, tol)?)
        };
        Ok(RunReport { implant, gravity })
    }
}

/// Whether the last [`STALL_WINDOW`] corotated cycles reduced the relative residual by
/// a factor worse than [`STALL_CONTRACTION`] per cycle (their geometric mean).
fn stalled(residuals: &[f64]) -> bool {
    match residuals.len().checked_sub(STALL_WINDOW + 1) {
        Some(start) => {
            let window = STALL_WINDOW as i32;
            residuals[residuals.len() - 1] > STALL_CONTRACTION.powi(window) * residuals[start]
        }
        None => false,
    }
}

/// Whether Newton-Krylov steps would bring stage 1 to `tolerance` at no more cost than
/// warped cycles converging at their last rate (`residuals`: the relative residuals
/// before the last corotated cycles, oldest first). The cycle after the last one starts
/// from the last residual times that rate, whichever kind it is; counted in warped
/// cycles, the next cycles cost `cycle_cost` each (1, or [`LAGGED_CYCLE_COST`] on kept
/// operators), a Newton-Krylov step costs [`NEWTON_KRYLOV_COST`] and contracts by
/// [`NEWTON_KRYLOV_CONTRACTION`], and the cycle whose residual meets the tolerance is
/// still run. A tie goes to the steps: a stalling iteration's rate only gets worse.
fn newton_krylov_pays(residuals: &[f64], tolerance: f64, cycle_cost: f64) -> bool {
    let [.., before, last] = residuals else {
        return false;
    };
    let rate = last / before;
    // a residual that grew, held or is not a number will not converge at this rate, nor
    // will any to a tolerance that is not positive
    if rate.is_nan() || rate >= 1.0 || tolerance.is_nan() || tolerance <= 0.0 {
        return true;
    }
    let next = last * rate;
    let cycles_after_next =
        |contraction: f64| ((tolerance / next).ln() / contraction.ln()).ceil().max(0.0);
    let warped = cycle_cost * (cycles_after_next(rate) + 1.0);
    let newton_krylov = NEWTON_KRYLOV_COST * (cycles_after_next(NEWTON_KRYLOV_CONTRACTION) + 1.0);
    warped >= newton_krylov
}

impl GravityStage {
    /// One cycle of stage 2: one iteration of conjugate gradients preconditioned by a
    /// symmetric V-cycle on the tangent system of the stage-1 state; `u` becomes stage
    /// 1's displacement plus the correction so far. Returns the residual before the
    /// iteration (mN) and its ratio to the stage's own load: against stage 1's reaction
    /// forces (the wall's, the fold's) the added weight's residual started below the
    /// tolerance and the correction stopped after one conjugate gradient step.
    fn cycle(&mut self, u: &mut [DVec3]) -> (f64, f64) {
        let mg = &mut self.multigrid.multigrid;
        let residual = self.iteration.residual_norm();
        self.iteration.step(mg);
        u.copy_from_slice(&self.u_implant);
        let sys = mg.system();
        for ((&v, d), &held) in sys
            .free
            .iter()
            .zip(self.iteration.solution())
            .zip(sys.eliminated())
        {
            if !held {
                u[v as usize] += *d;
            }
        }
        (residual, residual / self.rhs_norm_mn.max(f64::MIN_POSITIVE))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Over the last [`STALL_WINDOW`] cycles: more than halved per cycle on average is
    /// progress, less (steady, slow or oscillating) is a stall, and too short a history
    /// is neither.
    #[test]
    fn a_stall_is_a_window_slower_than_halving() {
        assert!(!stalled(&[1.0, 0.4, 0.16]));
        assert!(!stalled(&[1.0, 0.1, 0.2]));
        assert!(stalled(&[1.0, 0.7, 0.5]));
        assert!(stalled(&[3.5e-3, 3.4e-3, 3.5e-3]));
        assert!(stalled(&[1.0, 1.2, 1.1]));
        assert!(!stalled(&[1.0, 1.0]));
        // only the window counts: the first entry here is before it
        assert!(stalled(&[9.0, 1.0, 0.9, 0.8]));
        assert!(!stalled(&[1.0, 1.0, 0.3, 0.1]));
    }

    /// Costs counted by hand, in warped cycles, with the cycle that meets the tolerance
    /// run too: at the rate 0.75 from 1.6e-3 the next cycle starts at 1.2e-3 and the one
    /// after at 9e-4 (two warped cycles against two Newton-Krylov steps' four); at 0.9
    /// from 3e-3, eleven warped cycles against two steps' four; rates of 1 or more never
    /// converge; below the tolerance and still falling, nothing pays.
    #[test]
    fn newton_krylov_steps_pay_only_where_warped_cycles_would_take_longer() {
        assert_eq!(NEWTON_KRYLOV_COST, 2.0);
        assert_eq!(NEWTON_KRYLOV_CONTRACTION, 0.2);
        let tolerance = 1e-3;
        assert!(!newton_krylov_pays(&[2.1333e-3, 1.6e-3], tolerance, 1.0));
        assert!(!newton_krylov_pays(
            &[2.096e-3, 1.378e-3, 1.064e-3],
            tolerance,
            1.0
        ));
        assert!(newton_krylov_pays(&[3.33e-3, 3e-3], tolerance, 1.0));
        assert!(newton_krylov_pays(&[3e-3, 3e-3], tolerance, 1.0));
        assert!(newton_krylov_pays(&[2e-3, 3e-3], tolerance, 1.0));
        assert!(!newton_krylov_pays(&[2e-4, 1.9e-4], tolerance, 1.0));
        // the tighter the tolerance, the more the steps pay
        assert!(newton_krylov_pays(
            &[2.096e-3, 1.378e-3, 1.064e-3],
            1e-6,
            1.0
        ));
        // rate 0.47 from 1.5e-2: 7.0e-3, 3.3e-3, 1.5e-3, 7.3e-4 (four warped cycles)
        // against 7.0e-3, 1.4e-3, 2.8e-4 (three steps, six)
        assert!(!newton_krylov_pays(&[3.2e-2, 1.5e-2], tolerance, 1.0));
        // a tie: rate 0.72 from 3.1e-3, 2.2e-3, 1.6e-3, 1.2e-3, 8.3e-4 (four warped
        // cycles) against 2.2e-3, 4.5e-4 (two steps, four)
        assert!(newton_krylov_pays(&[4.3e-3, 3.1e-3], tolerance, 1.0));
        // the same on kept operators at half a warped cycle each: four cycles cost two
        // warped ones, against the steps' four
        assert!(!newton_krylov_pays(
            &[4.3e-3, 3.1e-3],
            tolerance,
            LAGGED_CYCLE_COST
        ));
        // the rate is the last pair's (0.83, not the window's first 0.9), counted from the
        // next cycle's start: 1.25e-3, 1.04e-3, 8.7e-4 (three warped cycles) against
        // 1.25e-3, 2.5e-4 (two steps, four); counted from the last residual, or at 0.9,
        // it would be a tie
        assert!(!newton_krylov_pays(
            &[2.0e-3, 1.8e-3, 1.5e-3],
            tolerance,
            1.0
        ));
        assert!(newton_krylov_pays(&[f64::NAN, 1e-3], tolerance, 1.0));
        assert!(newton_krylov_pays(&[2e-3, 1e-3], 0.0, 1.0));
        assert!(!newton_krylov_pays(&[1.0], tolerance, 1.0));
    }
}
