//! What the mouse does to a simulation: picking particles and triangles along a ray,
//! grabbing and dragging a particle, cutting particles and severing springs along a stroke.
//! Each call checks its rays first and changes nothing when one is bad.

use glam::{DVec2, Vec3};

use super::Simulation;
use crate::cutting::{piece_labels_joined_by, Crossing, MeshCrossing};
use crate::cutting_rest::{
    Cut, Layer, LayeredStroke, LiveStroke, MeshSheet, Reach, RestSheet, SheetPoint, MAX_LAYERS,
};
use crate::error::{Error, Result};
use crate::interaction::{Grab, DRAG_TIME, GRIP_SLIDE_ROUNDS, GRIP_SPACINGS};
use crate::model::Model;
use crate::picking::pick_triangle_scan;
use crate::picking::STROKE_TREE_MIN_RAYS;
use crate::picking::{BvhStats, ParticleHit, PickStrategy, Picker, Queries, TriangleHit};
use crate::ray::Ray;

impl Simulation {
    /// Half-size in m of the box around each particle that `pick` tests the ray against.
    pub fn pick_radius(&self) -> f32 {
        self.picker.radius(&self.model)
    }

    /// Sets the pick radius (m, finite and > 0).
    pub fn set_pick_radius(&mut self, radius: f64) -> Result<()> {
        self.picker.set_radius(radius)
    }

    /// How queries are answered (see [`PickStrategy`]).
    pub fn pick_strategy(&self) -> PickStrategy {
        self.picker.strategy()
    }

    pub fn set_pick_strategy(&mut self, strategy: PickStrategy) {
        self.picker.set_strategy(strategy);
    }

    /// Work done on the picking trees so far.
    pub fn bvh_stats(&self) -> BvhStats {
        self.picker.stats()
    }

    /// The live particle whose box the ray `origin + t direction` (t >= 0) enters first: its
    /// index, the distance along the ray (m) and the distance from the ray; ties go to the
    /// particle nearer the ray. `None` if the ray misses every particle. Errors (changing
    /// nothing) on a non-finite origin or a zero or non-finite direction.
    pub fn pick(&mut self, origin: Vec3, direction: Vec3) -> Result<Option<ParticleHit>> {
        let ray = Ray::new(origin, direction)?;
        Ok(self
            .picker
            .particle(&self.model, &self.state, &ray, Queries::One))
    }

    /// The live triangle the ray hits first: its position in [`Simulation::triangles`], the
    /// distance along the ray (m) and the barycentric weights of its three vertices. Errors as
    /// [`Simulation::pick`].
    pub fn pick_triangle(&mut self, origin: Vec3, direction: Vec3) -> Result<Option<TriangleHit>> {
        let ray = Ray::new(origin, direction)?;
        Ok(self.picker.triangle(&self.model, &self.state, &ray))
    }

    // ----- dragging and cutting -------------------------------------------------------------

    /// Radius in m of the patch a grab holds (see [`Simulation::grab`]). Defaults to
    /// [`GRIP_SPACINGS`] times the smaller grid spacing (a mesh cloth's mean edge length).
    pub fn grip_radius(&self) -> f32 {
        self.grip_radius
            .unwrap_or_else(|| (GRIP_SPACINGS * self.model.min_spacing()) as f32)
    }

    /// Sets the grip radius (m, finite and >= 0; 0 grabs the one particle hit). It applies
    /// from the next grab.
    pub fn set_grip_radius(&mut self, radius: f64) -> Result<()> {
        self.grip_radius = Some(crate::interaction::checked_grip_radius(radius)?);
        Ok(())
    }

    /// Time in s a [`Simulation::drag_to`] takes to carry the grip to its target (see
    /// [`DRAG_TIME`], the default).
    pub fn drag_time(&self) -> f64 {
        self.drag_time.unwrap_or(DRAG_TIME)
    }

    /// Sets the drag time (s, finite and >= 0; 0 puts the grip on each target in the next
    /// substep). It applies from the next `drag_to`.
    pub fn set_drag_time(&mut self, seconds: f64) -> Result<()> {
        self.drag_time = Some(crate::interaction::checked_drag_time(seconds)?);
        Ok(())
    }

    /// Grabs the cloth at particle `index`: that particle and every live particle within
    /// [`Simulation::grip_radius`] of it joined to it by live springs inside that ball (a
    /// patch of cloth, as a hand holds it) become kinematic pins where they are, which
    /// [`Simulation::drag_to`] moves together. Grabbing while holding releases the grip first.
    /// Errors on an index out of range or a cut particle.
    pub fn grab(&mut self, index: i64) -> Result<()> {
        let p = self.check_index("index", index)?;
        if !self.model.particles.alive[p] {
            return Err(Error::value(
                "index",
                format!("particle {p} was cut and cannot be grabbed"),
            ));
        }
        self.release();
        let grab = Grab::around(p, self.grip_radius(), &self.model, &self.state);
        for held in &grab.held {
            self.pin_live(held.index, Some(self.state.kin.pos.get(held.index)));
        }
        self.grab = Some(grab);
        Ok(())
    }

    /// Moves the grip so that the grabbed particle's target is `target` (m) and every other
    /// particle of the grip moves by the same displacement from where it was grabbed. The
    /// grip glides there from where it is now at a constant velocity, arriving
    /// [`Simulation::drag_time`] later, and the cloth follows through its springs. A hand cannot
    /// push cloth into a solid: the grip is raised as a whole above the floor, and where its
    /// move would take a particle into a collider posed at the arrival time (by the contact
    /// test the step runs) the whole grip slides along that collider instead: the move loses
    /// its part into the surface where the deepest particle meets it and keeps the part along
    /// it, repeated for the next deepest ([`GRIP_SLIDE_ROUNDS`] at most). So the patch keeps
    /// its shape round a collider, as a hand's grip does, and a pair of the grip's own
    /// particles never closes for the self-collision pass to stop. A particle still touching
    /// after that goes where the collider puts a particle taking its own path. Colliders skip
    /// pinned particles, so a target left inside one would hold the grip there while the
    /// collider pushed the cloth round it out, tearing the grip's rim. Without a grab (or once
    /// the grabbed particle was cut) this does nothing; particles of the grip cut since are
    /// skipped. Errors on a non-finite target.
    pub fn drag_to(&mut self, target: Vec3) -> Result<()> {
        if !target.is_finite() {
            return Err(Error::value(
                "target",
                format!("must be finite, got {:?}", target.to_array()),
            ));
        }
        let alive = &self.model.particles.alive;
        let Some(grab) = self.grab.as_ref().filter(|g| alive[g.index()]) else {
            return Ok(());
        };
        let first = grab.index();
        let now = self.state.clock.time(self.model.scene.dt);
        let here = self.glide_start(first, now);
        let over = self.drag_time();
        let target = self.above_floor(target);
        let target = self.slid_along_colliders(target, now, now + over);
        let Some(grab) = self.grab.as_ref() else {
            return Ok(());
        };
        let mut moves = Vec::with_capacity(grab.held.len());
        for (p, to) in grab.targets(target) {
            if !self.model.particles.alive[p] || !to.is_finite() {
                continue;
            }
            // Pinned again in case `unpin` was called during the drag.
            self.model.particles.set_pinned(p, true);
            let from = self.glide_start(p, now);
            moves.push((p, self.stepper.push_out(from, to, now + over)));
        }
        self.state.targets.glide_to(&moves, here, now, over);
        Ok(())
    }

    /// Where particle `p`'s glide starts at time `now` (s): on its glide's path where it has
    /// one, else where it is.
    fn glide_start(&self, p: usize, now: f64) -> Vec3 {
        (self.state.targets.at(p, now)).unwrap_or(self.state.kin.pos.get(p))
    }

    /// `target` for the grabbed particle such that the grip, moved as one from where its
    /// targets are at `now`, ends clear of the colliders posed at `arrival` (s). Each round
    /// shifts the whole move along the normal of the deepest particle's contact by that
    /// particle's depth, which puts it on the contact's tangent plane: the move's part into
    /// the surface goes, its part along the surface stays, so the grip slides round a collider
    /// rather than stopping where it meets it or changing shape. `target` itself, bit for bit,
    /// where no particle touches.
    fn slid_along_colliders(&self, target: Vec3, now: f64, arrival: f64) -> Vec3 {
        let Some(grab) = self.grab.as_ref() else {
            return target;
        };
        let alive = &self.model.particles.alive;
        let mut slid = target;
        for _ in 0..GRIP_SLIDE_ROUNDS {
            let deepest = (grab.targets(slid))
                .filter(|&(p, to)| alive[p] && to.is_finite())
                .filter_map(|(p, to)| {
                    let (n, at) = self
                        .stepper
                        .contact(self.glide_start(p, now), to, arrival)?;
                    Some(((at - to).dot(n), n))
                })
                .max_by(|a, b| a.0.total_cmp(&b.0));
            match deepest {
                Some((depth, n)) if depth > 0.0 => slid += depth * n,
                _ => break,
            }
        }
        slid
    }

    /// `target` for the grabbed particle, raised as far as it takes to keep every particle of
    /// the grip on or above the floor: a hand cannot pull cloth through the floor, and a grip
    /// held under it while the floor holds the cloth round it up tears the grip's rim, plucking
    /// the patch out of the sheet (a straight-down drag of `tear`, taken past the floor).
    fn above_floor(&self, target: Vec3) -> Vec3 {
        let (Some(floor), Some(grab)) = (&self.model.scene.floor, &self.grab) else {
            return target;
        };
        let level = (floor.height + floor.thickness) as f32;
        let lowest = grab
            .targets(target)
            .map(|(_, to)| to.y)
            .fold(f32::INFINITY, f32::min);
        target + Vec3::Y * (level - lowest).max(0.0)
    }

    /// Lets go of the grip, restoring the pin state each of its particles had before the
    /// grab: a free particle keeps the velocity of the drag; a statically pinned one stays
    /// pinned where it is now; one that had a kinematic target gets it back. Without a grab
    /// this does nothing.
    pub fn release(&mut self) {
        let Some(grab) = self.grab.take() else {
            return;
        };
        for held in grab.held {
            let p = held.index;
            if !self.model.particles.alive[p] {
                continue; // cut while grabbed: the cut already removed the pin
            }
            if held.was_pinned {
                self.pin_live(p, held.previous_target);
            } else {
                self.model.particles.set_pinned(p, false);
                self.state.targets.remove(p);
            }
        }
    }

    /// The particle the grip was taken at, if any (a grip whose grabbed particle was cut is
    /// let go).
    pub fn grabbed(&self) -> Option<usize> {
        self.grab
            .as_ref()
            .map(Grab::index)
            .filter(|&p| self.model.particles.alive[p])
    }

    /// Every live particle the grip holds, the grabbed one first; empty without a grab.
    pub fn gripped(&self) -> Vec<usize> {
        if self.grabbed().is_none() {
            return Vec::new();
        }
        self.grab.as_ref().map_or_else(Vec::new, |g| {
            g.held
                .iter()
                .map(|h| h.index)
                .filter(|&p| self.model.particles.alive[p])
                .collect()
        })
    }

    /// Cuts the particle [`Simulation::pick`] finds along the ray; returns it, or `None` if the
    /// ray hits nothing.
    pub fn cut_ray(&mut self, origin: Vec3, direction: Vec3) -> Result<Option<usize>> {
        let ray = Ray::new(origin, direction)?;
        Ok(self.cut_along(&ray, Queries::One))
    }

    /// Cuts, ray after ray, the particle each ray of a mouse stroke picks (a later ray sees
    /// the cloth without the particles cut before it); returns the particles cut, in order.
    /// Every ray is checked before anything is cut, so bad input changes nothing. Sample the
    /// stroke densely enough (about one ray per grid spacing on screen) to leave no gaps.
    pub fn cut_stroke(&mut self, rays: &[(Vec3, Vec3)]) -> Result<Vec<usize>> {
        let rays = checked_rays(rays)?;
        let queries = if rays.len() >= STROKE_TREE_MIN_RAYS {
            Queries::Many
        } else {
            Queries::One
        };
        Ok(rays
            .iter()
            .filter_map(|ray| self.cut_along(ray, queries))
            .collect())
    }

    /// Makes the scene's `[[cloth.cuts]]` in the cloth as built, each dash a stroke (each one
    /// counted in `topology_version`, as a user's strokes are). A cut that severs no spring
    /// (it misses the cloth, or its dashes fall between springs) is an error naming it, as a
    /// cut that does nothing is a mistake in the scene.
    pub(super) fn make_scene_cuts(&mut self) -> Result<()> {
        let cloth = &self.model.scene.cloth;
        let strokes: Vec<_> = (cloth.cuts.iter())
            .map(|cut| cut.strokes(cloth.plane.axes(), cloth.center))
            .collect();
        for (k, dashes) in strokes.iter().enumerate() {
            let mut severed = 0;
            for rays in dashes {
                severed += self.sever_stroke(rays)?;
            }
            if severed == 0 {
                return Err(Error::value(
                    format!("cloth.cuts[{k}]"),
                    "severs no spring of the cloth: its points must lie across the cloth as built",
                ));
            }
        }
        Ok(())
    }

    /// Severs the cloth along a mouse stroke: every live spring whose segment crosses the
    /// surface the rays sweep between consecutive samples (the quad from one ray to the next,
    /// reaching through the whole cloth) is severed, and the mesh's triangles across it go.
    /// Returns how many springs were severed. No particle is removed, so the cloth's mass is
    /// exactly what it was, and a grabbed particle stays grabbed on whichever piece it is now.
    /// On a mesh cloth the springs are its list's edge and bend springs: an edge severed takes
    /// the bend springs of its triangles with it, uncounted ([`crate::mesh_cloth::topology`]).
    ///
    /// Every ray is checked before anything changes (an error names `rays[k].origin` or
    /// `rays[k].direction`). Documented no-ops, returning 0 with nothing changed (not even the
    /// topology version): fewer than two rays (a click sweeps no surface), rays that do not
    /// move (a stroke of zero length), a stroke that misses the cloth or crosses only springs
    /// already severed (cutting a piece that is already separate along the same line).
    pub fn sever_stroke(&mut self, rays: &[(Vec3, Vec3)]) -> Result<usize> {
        self.sever_stroke_with(rays, &mut || false)
    }

    /// [`Simulation::sever_stroke`], asking `interrupted` now and then while it looks for the
    /// springs to sever (a stroke of millions of rays takes seconds); an interrupted stroke
    /// severs nothing and returns [`Error::Interrupted`].
    pub fn sever_stroke_with(
        &mut self,
        rays: &[(Vec3, Vec3)],
        interrupted: &mut dyn FnMut() -> bool,
    ) -> Result<usize> {
        let rays = checked_rays(rays)?;
        self.sever_checked(&rays, interrupted)
    }

    /// [`Simulation::sever_stroke_with`] on rays already checked: the springs the surface
    /// `rays` sweep through the cloth as it is now crosses, severed.
    fn sever_checked(
        &mut self,
        rays: &[Ray],
        interrupted: &mut dyn FnMut() -> bool,
    ) -> Result<usize> {
        let model = &self.model;
        if let Some(mesh) = model.mesh() {
            let at = (&self.state.kin.pos, &model.particles.alive[..]);
            let crossings = self
                .cutter
                .mesh_crossings(&mesh.springs, at, rays, interrupted);
            return match crossings {
                Some(crossings) => Ok(self.model.sever_mesh_crossing(crossings)),
                None => Err(Error::Interrupted { steps: 0 }),
            };
        }
        let crossings = self.cutter.crossings(
            model.grid,
            &model.springs,
            &model.particles.alive,
            &self.state.kin.pos,
            rays,
            interrupted,
        );
        match crossings {
            Some(crossings) => Ok(self.model.sever_crossing(crossings)),
            None => Err(Error::Interrupted { steps: 0 }),
        }
    }

    /// Continues the live stroke in progress (a mouse drag drawn over several frames, the
    /// cloth moving between them) with `rays`, this frame's samples of it, and severs the
    /// springs it crosses; returns how many. The first call after
    /// [`Simulation::end_live_stroke`] starts a stroke.
    ///
    /// On the grid the stroke is held in the cloth's own coordinates
    /// ([`crate::cutting_rest`]): each ray that hits the cloth (its triangles, severed or not,
    /// so that a ray over the slit already cut still names the material under it) names a
    /// point of the rest sheet, and consecutive points, the previous frame's last among them,
    /// are joined on that sheet, so the cut goes through the material the mouse passed over
    /// whatever the cloth did between frames. A stroke that comes onto the cloth from off it
    /// is carried back out from its first point through the sheet's edge, and one that leaves
    /// it out from its last point, each along the stroke's direction over about a spacing on
    /// the sheet and at most [`REST_JUMP_SPACINGS`] spacings: so a stroke from off the cloth
    /// to off it separates it, even where it came on over a curl seen edge on. Two
    /// consecutive points farther apart than that on the sheet (the stroke went over a fold's
    /// edge onto another layer) are cut by the surface their rays sweep through the cloth as
    /// it is now ([`Simulation::sever_stroke`]).
    ///
    /// A mesh cloth whose rest shape is flat has a rest sheet too ([`MeshSheet`]): the plane
    /// fitted to its rest positions, or a garment's flat panels, one chart each. There every
    /// layer a ray passes through is followed on the sheet, each on its own line
    /// ([`LayeredStroke`]: on one layer it cuts what the grid's stroke cuts); two consecutive
    /// front points on different panels (the stroke crossed a seam) are cut by the surface
    /// their rays sweep, as a jump is. On a mesh whose rest shape is curved every pair of rays
    /// is cut by its swept surface, the last frame's last ray joined to this frame's first.
    ///
    /// On the grid the layers hidden behind the first one a ray meets are cut by the surface
    /// the frame's rays sweep, on those layers only ([`HIDDEN_LAYER_SPACINGS`]). The cuts
    /// behind the front, on either, are dropped where they would cut out a piece of fewer than
    /// [`HIDDEN_LAYER_MIN_PIECE`] particles.
    ///
    /// Every ray is checked before anything changes, as in [`Simulation::sever_stroke`].
    pub fn sever_live_stroke(&mut self, rays: &[(Vec3, Vec3)]) -> Result<usize> {
        let rays = checked_rays(rays)?;
        let Some(&last) = rays.last() else {
            return Ok(0);
        };
        let Some(topology) = self.model.mesh_topology() else {
            let sheet = self.rest_sheet();
            let step = sheet.spacing.min_element();
            // Every ray meets the cloth as it is at the start of this frame's piece: the
            // points are picked before any spring goes.
            let (grid, pos) = (self.model.grid, &self.state.kin.pos);
            let alive = &self.model.particles.alive;
            let hits: Vec<Option<TriangleHit>> = (rays.iter())
                .map(|ray| pick_triangle_scan(ray, grid, pos, alive))
                .collect();
            let points: Vec<Option<SheetPoint>> = (hits.iter())
                .map(|hit| hit.map(|hit| (0, sheet.at(hit.index, hit.barycentric))))
                .collect();
            let exit = |_: u32, from: DVec2, dir: DVec2| sheet.exit_distance(from, dir);
            let margin = (HIDDEN_LAYER_SPACINGS * step) as f32;
            let hidden = self.hidden_layer_crossings((&rays, &hits), margin);
            let severed = self.live_cuts(&rays, &points, step, exit, |sim, cut, out| match cut {
                Cut::Rest(_, a, b) => {
                    let alive = &sim.model.particles.alive;
                    sheet.crossings(&sim.model.springs, alive, (a, b), out);
                }
                Cut::Swept(r0, r1) => out.extend_from_slice(sim.grid_swept_crossings(&[r0, r1])),
            });
            // The hidden layers' crossings are one swept cut's.
            let hidden = self.without_slivers(hidden.into_iter().map(|c| (c, 0)).collect());
            return Ok(severed + Crossing::sever(&mut self.model, &hidden));
        };
        let sheet = self
            .mesh_sheet
            .get_or_insert_with(|| MeshSheet::new(topology))
            .take();
        let Some(sheet) = sheet else {
            // A curved rest shape: every pair of rays is cut by its swept surface.
            self.mesh_sheet = Some(None);
            let previous = self.live.last_ray.replace(last);
            let stroke: Vec<Ray> = previous.into_iter().chain(rays).collect();
            return self.sever_checked(&stroke, &mut || false);
        };
        // Every triangle whose corners are alive, severed or not, names the material under it.
        let margin = (HIDDEN_LAYER_SPACINGS * sheet.spacing) as f32;
        let layers: Vec<Vec<SheetPoint>> = (self.layer_hits(&rays, margin).into_iter())
            .map(|hits| {
                (hits.into_iter())
                    .map(|hit| sheet.at(hit.index, hit.barycentric))
                    .collect()
            })
            .collect();
        let exit = |c: u32, from: DVec2, dir: DVec2| sheet.exit_distance(c, from, dir);
        let reach = Reach {
            step: sheet.spacing,
            jump: REST_JUMP_SPACINGS * sheet.spacing,
        };
        // The frame's cuts are severed together, each spring at the first crossing listed: the
        // front layer's, then the layers' behind less any that would cut out a sliver, which
        // the filter weighs against the whole frame's cut.
        let (mut cuts, mut front, mut behind) = (Vec::new(), Vec::new(), Vec::new());
        // Each crossing behind with the cut it came from (numbered through the frame).
        let (mut crossings, mut cut_id) = (Vec::new(), 0u32);
        for (&ray, hits) in rays.iter().zip(&layers) {
            cuts.clear();
            self.layers
                .advance(ray, hits, reach, exit, |cut, layer| cuts.push((cut, layer)));
            let Some(mesh) = self.model.mesh() else {
                break;
            };
            let at = (&self.state.kin.pos, &self.model.particles.alive[..]);
            for &(cut, layer) in &cuts {
                crossings.clear();
                match cut {
                    Cut::Rest(c, a, b) => {
                        sheet.crossings(c, (&mesh.springs, at.1), (a, b), &mut crossings)
                    }
                    Cut::Swept(r0, r1) => {
                        let swept =
                            (self.cutter)
                                .mesh_crossings(&mesh.springs, at, &[r0, r1], &mut || false);
                        crossings.extend_from_slice(swept.unwrap_or_default());
                    }
                }
                match layer {
                    Layer::Front => front.extend_from_slice(&crossings),
                    Layer::Behind => behind.extend(crossings.iter().map(|&c| (c, cut_id))),
                }
                cut_id += 1;
            }
        }
        let mut severed = MeshCrossing::sever(&mut self.model, &front);
        let behind = self.without_slivers(behind);
        severed += MeshCrossing::sever(&mut self.model, &behind);
        self.mesh_sheet = Some(Some(sheet));
        Ok(severed)
    }

    /// Every layer of material each ray meets, nearest first: the hits on triangles whose
    /// corners are alive (severed or not), each the first more than `margin` (m) past the
    /// last along the ray, at most [`MAX_LAYERS`]. Nearer than `margin` behind a hit, a second
    /// hit is the same layer (a fold's two sides meet there on the sheet too).
    fn layer_hits(&mut self, rays: &[Ray], margin: f32) -> Vec<Vec<TriangleHit>> {
        let mut layers: Vec<Vec<TriangleHit>> = vec![Vec::new(); rays.len()];
        // (which ray, the probe, how far along the ray the probe starts)
        let mut probes: Vec<(usize, Ray, f32)> =
            rays.iter().enumerate().map(|(k, &r)| (k, r, 0.0)).collect();
        for _ in 0..MAX_LAYERS {
            if probes.is_empty() {
                break;
            }
            let queries: Vec<Ray> = probes.iter().map(|p| p.1).collect();
            let found = (self.picker).material_triangles(&self.model, &self.state, &queries);
            let mut next = Vec::with_capacity(probes.len());
            for ((k, probe, start), hit) in probes.into_iter().zip(found) {
                let Some(hit) = hit else { continue };
                layers[k].push(TriangleHit {
                    distance: start + hit.distance,
                    ..hit
                });
                let skip = hit.distance + margin;
                if let Ok(past) = Ray::new(probe.origin + probe.dir * skip, probe.dir) {
                    next.push((k, past, start + skip));
                }
            }
            probes = next;
        }
        layers
    }

    /// `hidden` (crossings on layers behind the first, each with the cut it came from) less
    /// those that would leave a piece of fewer than [`HIDDEN_LAYER_MIN_PIECE`] particles once
    /// severed with the springs already gone: where a layer behind is cut at a grazing angle,
    /// or its cut runs beside the first layer's where a layer turns into the first one, it
    /// isolates a particle or two, which no one meant to cut out.
    fn without_slivers<C: Sliver>(&self, mut hidden: Vec<(C, u32)>) -> Vec<C> {
        let alive = &self.model.particles.alive;
        // Dropping crossings only joins pieces, so a few rounds settle it; none to weigh (a
        // stroke over one layer), no `O(n)` labelling.
        for _ in 0..if hidden.is_empty() { 0 } else { 4 } {
            let label = C::pieces_without(self, hidden.iter().map(|h| h.0));
            let mut size = vec![0usize; alive.len()];
            for p in (0..alive.len()).filter(|&p| alive[p]) {
                size[label[p] as usize] += 1;
            }
            let small = |p: usize| size[label[p] as usize] < HIDDEN_LAYER_MIN_PIECE;
            // A sliver goes back to one side only, and only through one cut's crossings: the
            // (side, cut) most of its crossings lead through (the lower on a tie). Given back
            // to both sides, it would join the two sides the cuts separate; given back through
            // both of two cuts that run either side of it, it would join them too once the
            // stroke separates them further on, though this frame they are one piece.
            let mut sides: std::collections::BTreeMap<(u32, u32, u32), usize> = Default::default();
            for &(c, from) in &hidden {
                let (a, b) = c.ends(self);
                for (p, q) in [(a, b), (b, a)] {
                    if small(p) && !small(q) {
                        *sides.entry((label[p], label[q], from)).or_default() += 1;
                    }
                }
            }
            let mut side: std::collections::BTreeMap<u32, (usize, (u32, u32))> = Default::default();
            for (&(sliver, to, from), &n) in &sides {
                let best = side.entry(sliver).or_insert((n, (to, from)));
                if n > best.0 {
                    *best = (n, (to, from));
                }
            }
            let before = hidden.len();
            hidden.retain(|&(c, from)| {
                let (a, b) = c.ends(self);
                let back = |p: usize, q: usize| {
                    small(p)
                        && (small(q)
                            || side.get(&label[p]).is_some_and(|s| s.1 == (label[q], from)))
                };
                !back(a, b) && !back(b, a)
            });
            if hidden.len() == before {
                break;
            }
        }
        hidden.into_iter().map(|h| h.0).collect()
    }

    /// The live springs of a grid cloth the surface `stroke` sweeps through it as it is now
    /// crosses ([`crate::cutting::StrokeCutter::crossings`]).
    fn grid_swept_crossings(&mut self, stroke: &[Ray]) -> &[Crossing] {
        let (model, pos) = (&self.model, &self.state.kin.pos);
        let alive = &model.particles.alive;
        (self.cutter)
            .crossings(model.grid, &model.springs, alive, pos, stroke, &mut || {
                false
            })
            .unwrap_or_default()
    }

    /// The crossings of the surface this frame's stroke sweeps through the cloth as it is now
    /// (`rays`, after the last frame's last ray) that lie on layers hidden behind the first
    /// one each ray meets: farther along the line of sight from the nearest ray's origin than
    /// the first material there by more than `margin` (m). The rest sheet cuts the layer under
    /// the mouse; a crumpled or folded cloth has layers behind it that the mouse passed over
    /// too, and cutting those by the swept surface leaves the first layer to the sheet alone:
    /// the two cuts never run side by side on one layer, which would isolate slivers between
    /// them. A grid cloth's: a mesh cloth follows its layers on the sheet ([`LayeredStroke`]).
    ///
    /// `hits` are the first hits of `rays`. Nothing is swept when no ray meets a second layer
    /// past its first hit (a flat or gently draped cloth): one more scan a ray.
    fn hidden_layer_crossings(
        &mut self,
        (rays, hits): (&[Ray], &[Option<TriangleHit>]),
        margin: f32,
    ) -> Vec<Crossing> {
        let stroke: Vec<Ray> = (self.live.last_ray.into_iter())
            .chain(rays.iter().copied())
            .collect();
        if stroke.len() < 2 {
            return Vec::new();
        }
        // A scan a ray (a tree would be refitted for these few queries on every frame).
        let (grid, pos, alive) = (
            self.model.grid,
            &self.state.kin.pos,
            &self.model.particles.alive,
        );
        let layer_behind = (rays.iter().zip(hits)).any(|(ray, hit)| {
            hit.and_then(|hit| {
                Ray::new(ray.origin + ray.dir * (hit.distance + margin), ray.dir).ok()
            })
            .is_some_and(|past| pick_triangle_scan(&past, grid, pos, alive).is_some())
        });
        if !layer_behind {
            return Vec::new();
        }
        let crossings = self.grid_swept_crossings(&stroke).to_vec();
        // The line of sight to each crossing, from the origin of the ray nearest it.
        let sights: Vec<Option<(Ray, f32)>> = (crossings.iter())
            .map(|&c| {
                let ((kind, anchor), t) = c;
                let partner = self.model.grid.partner(anchor, kind).unwrap_or(anchor);
                let pos = &self.state.kin.pos;
                let x = pos.get(anchor).lerp(pos.get(partner), t);
                let off = |r: &Ray| {
                    (x - r.origin)
                        .reject_from_normalized(r.dir)
                        .length_squared()
                };
                let nearest = stroke.iter().min_by(|a, b| off(a).total_cmp(&off(b)))?;
                let to = x - nearest.origin;
                Some((Ray::new(nearest.origin, to).ok()?, to.length()))
            })
            .collect();
        let lines: Vec<Ray> = sights.iter().flatten().map(|s| s.0).collect();
        let mut first = (self.picker)
            .material_triangles(&self.model, &self.state, &lines)
            .into_iter();
        (crossings.into_iter().zip(sights))
            .filter(|(_, sight)| {
                let Some((_, far)) = sight else {
                    return false;
                };
                let first = first.next().flatten();
                first.is_some_and(|hit| *far > hit.distance + margin)
            })
            .map(|(c, _)| c)
            .collect()
    }

    /// The live stroke's course over the rest sheet for this frame's `rays`, which hit the
    /// material `points`: for each ray, what [`LiveStroke::advance`] hands on, turned into
    /// crossings by `crossings` and severed before the next ray. Returns how many springs went.
    fn live_cuts<C: Severed>(
        &mut self,
        rays: &[Ray],
        points: &[Option<SheetPoint>],
        step: f64,
        exit: impl Fn(u32, DVec2, DVec2) -> f64,
        mut crossings: impl FnMut(&mut Simulation, Cut, &mut Vec<C>),
    ) -> usize {
        let reach = Reach {
            step,
            jump: REST_JUMP_SPACINGS * step,
        };
        let mut severed = 0;
        let mut out = Vec::new();
        for (&ray, &here) in rays.iter().zip(points) {
            out.clear();
            let mut cuts = [None; 3];
            let mut n = 0;
            self.live.advance(ray, here, reach, &exit, |cut| {
                cuts[n] = Some(cut);
                n += 1;
            });
            for cut in cuts.into_iter().flatten() {
                crossings(self, cut, &mut out);
            }
            severed += C::sever(&mut self.model, &out);
        }
        severed
    }
    /// Ends the live stroke in progress: the next [`Simulation::sever_live_stroke`] starts a
    /// new one, joined to nothing.
    pub fn end_live_stroke(&mut self) {
        self.live = LiveStroke::default();
        self.layers = LayeredStroke::default();
    }

    /// The grid's rest sheet: `(i dx, j dy)` with the scene's size over the cells.
    fn rest_sheet(&self) -> RestSheet {
        let (grid, size) = (self.model.grid, self.model.scene.cloth.size);
        let cells = DVec2::new((grid.nx - 1) as f64, (grid.ny - 1) as f64);
        RestSheet {
            grid,
            spacing: DVec2::new(size[0], size[1]) / cells,
        }
    }

    /// The number of pieces the cloth is in: connected components of the live particles
    /// joined by live springs (`O(n)`).
    pub fn pieces(&self) -> usize {
        let model = &self.model;
        if let Some(topology) = model.mesh_topology() {
            let mut labels = topology.piece_labels(&model.particles.alive);
            labels.retain(|&l| l != u32::MAX);
            labels.sort_unstable();
            labels.dedup();
            return labels.len();
        }
        crate::cutting::pieces(model.grid, &model.springs, &model.particles.alive)
    }

    /// The piece each particle belongs to, named by the smallest particle index in it
    /// (`u32::MAX` for a removed particle).
    pub fn piece_labels(&self) -> Vec<u32> {
        let model = &self.model;
        if let Some(topology) = model.mesh_topology() {
            return topology.piece_labels(&model.particles.alive);
        }
        crate::cutting::piece_labels(model.grid, &model.springs, &model.particles.alive)
    }

    /// Whether the spring of `kind` anchored at particle `anchor` is live (false for a slot
    /// off the grid, or a spring cut, severed or torn).
    pub fn spring_live(&self, kind: crate::grid::SpringKind, anchor: usize) -> bool {
        self.model.springs.active[kind.index()]
            .get(anchor)
            .is_some_and(|&a| a != 0.0)
    }

    /// Cuts the particle `ray` picks, removing its leaves from the picking trees that were up
    /// to date: a cut moves nothing, so they stay valid without a refit.
    fn cut_along(&mut self, ray: &Ray, queries: Queries) -> Option<usize> {
        let p = self
            .picker
            .particle(&self.model, &self.state, ray, queries)?
            .index;
        let before = Picker::versions(&self.model, &self.state);
        self.cut_live(p);
        self.picker.after_cut(&self.model, &self.state, p, before);
        Some(p)
    }
}

/// How far apart on the rest sheet, in rest spacings, two consecutive points of a live stroke
/// may be and still be joined there (default 8). Farther apart, the stroke went from one layer
/// of the cloth to another (over a fold's edge) rather than across the material between them,
/// and a rest segment would cut everything between the two; those two rays are cut by the
/// surface they sweep instead. It has to allow for what the material under the mouse moves
/// between two frames of a slow display.
pub const REST_JUMP_SPACINGS: f64 = 8.0;

/// A severed spring with where a stroke crossed it, grid's or mesh's.
trait Severed: Copy {
    /// Severs the springs `crossings` lists (see [`Model::sever_crossing`]); how many were live.
    fn sever(model: &mut Model, crossings: &[Self]) -> usize;
}

impl Severed for Crossing {
    fn sever(model: &mut Model, crossings: &[Self]) -> usize {
        model.sever_crossing(crossings)
    }
}

impl Severed for MeshCrossing {
    fn sever(model: &mut Model, crossings: &[Self]) -> usize {
        model.sever_mesh_crossing(crossings)
    }
}

/// The rays of a stroke, each checked and named `rays[k].origin` / `rays[k].direction`.
fn checked_rays(rays: &[(Vec3, Vec3)]) -> Result<Vec<Ray>> {
    rays.iter()
        .enumerate()
        .map(|(k, &(o, d))| {
            let (origin, dir) = (format!("rays[{k}].origin"), format!("rays[{k}].direction"));
            Ray::named(o, d, &origin, &dir)
        })
        .collect()
}

/// How far behind the first layer a ray meets, in rest spacings (the grid's smaller one), a
/// layer must lie for the live stroke to cut it by the swept surface
/// ([`Simulation::sever_live_stroke`]); 1. Nearer, it counts as the first layer itself (a bending
/// spring's chord lies off the surface, and the swept surface meets the first layer between
/// two rays at depths between theirs), which the rest sheet already cuts: a second cut beside
/// the first would isolate slivers. Farther, a fold lying closer behind is left whole.
pub const HIDDEN_LAYER_SPACINGS: f64 = 1.0;

/// A crossing [`Simulation::without_slivers`] can weigh: its spring's two particles, and the
/// pieces the cloth would be in with some crossings' springs severed too.
trait Sliver: Copy {
    fn ends(self, sim: &Simulation) -> (usize, usize);
    fn pieces_without(sim: &Simulation, cut: impl Iterator<Item = Self>) -> Vec<u32>;
}

impl Sliver for Crossing {
    fn ends(self, sim: &Simulation) -> (usize, usize) {
        let ((kind, anchor), _) = self;
        let partner = sim.model.grid.partner(anchor, kind).unwrap_or(anchor);
        (anchor.min(partner), anchor.max(partner))
    }

    fn pieces_without(sim: &Simulation, cut: impl Iterator<Item = Self>) -> Vec<u32> {
        let model = &sim.model;
        let cut: std::collections::HashSet<(usize, usize)> = cut.map(|c| c.ends(sim)).collect();
        let joins = |a: usize, b: usize| !cut.contains(&(a.min(b), a.max(b)));
        piece_labels_joined_by(model.grid, &model.springs, &model.particles.alive, joins)
    }
}

impl Sliver for MeshCrossing {
    fn ends(self, sim: &Simulation) -> (usize, usize) {
        let e = self.0 as usize;
        (sim.model.mesh()).map_or((0, 0), |m| {
            (m.springs.a[e] as usize, m.springs.b[e] as usize)
        })
    }

    fn pieces_without(sim: &Simulation, cut: impl Iterator<Item = Self>) -> Vec<u32> {
        let Some(topology) = sim.model.mesh_topology() else {
            return sim.piece_labels();
        };
        let cut: std::collections::HashSet<u32> = cut.map(|c| c.0).collect();
        topology.piece_labels_joined_by(&sim.model.particles.alive, |e| !cut.contains(&e))
    }
}

/// The fewest particles a piece the hidden layers' cut leaves may hold (3): fewer is a sliver.
pub const HIDDEN_LAYER_MIN_PIECE: usize = 3;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::picking::pick_triangle_brute_force_where;
    use crate::scene::Scene;

    /// Rays along each axis through a lattice over the cloth's bounding box, and slanted ones.
    fn rays_over(pos: &crate::soa::Vec3s, alive: &[bool], k: usize) -> Vec<Ray> {
        let live = (0..pos.len()).filter(|&p| alive[p]).map(|p| pos.get(p));
        let (lo, hi) = live.fold((Vec3::MAX, Vec3::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
        let mut rays = Vec::new();
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for i in 0..k {
                for j in 0..k {
                    let (s, t) = ((i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32);
                    let mut origin = lo - Vec3::ONE;
                    origin[u] = lo[u] + s * (hi[u] - lo[u]);
                    origin[v] = lo[v] + t * (hi[v] - lo[v]);
                    let mut dir = Vec3::ZERO;
                    dir[axis] = 1.0;
                    rays.push(Ray::new(origin, dir).unwrap());
                    rays.push(Ray::new(origin, dir + 0.3 * Vec3::ONE).unwrap());
                }
            }
        }
        rays
    }

    #[test]
    fn the_live_stroke_tree_pick_equals_testing_every_material_triangle_on_a_cut_moving_mesh() {
        let mut sim = Simulation::new(Scene::builtin("flag_hole").unwrap()).unwrap();
        sim.picker.set_strategy(PickStrategy::Bvh);
        sim.advance(1.0).unwrap();
        let mut severed_hits = 0;
        for round in 0..3 {
            // A stroke across the crumpled flag, frame by frame with the cloth moving between,
            // and a particle cut out, so that the tree has both kinds of change to follow.
            let live: Vec<usize> = (0..sim.model.grid.len())
                .filter(|&p| sim.model.particles.alive[p])
                .collect();
            let probe = rays_over(&sim.state.kin.pos, &sim.model.particles.alive, 6);
            for frame in probe.chunks(12).take(4) {
                let frame: Vec<(Vec3, Vec3)> = frame.iter().map(|r| (r.origin, r.dir)).collect();
                sim.sever_live_stroke(&frame).unwrap();
                sim.advance(0.02).unwrap();
            }
            sim.end_live_stroke();
            sim.cut(live[live.len() / (round + 2)] as i64).unwrap();
            sim.advance(0.05).unwrap();

            let (model, state) = (&sim.model, &sim.state);
            let topology = model.mesh_topology().unwrap();
            let alive = &model.particles.alive;
            let rays = rays_over(&state.kin.pos, alive, 24);
            let tree = sim.picker.material_triangles(model, state, &rays);
            assert_eq!(tree.len(), rays.len());
            for (ray, hit) in rays.iter().zip(tree) {
                let all = pick_triangle_brute_force_where(
                    ray,
                    &state.kin.pos,
                    &topology.triangles,
                    |t| topology.triangles[t].iter().all(|&v| alive[v as usize]),
                );
                assert_eq!(hit, all, "round {round}, ray {ray:?}");
                severed_hits += hit.is_some_and(|h| !model.triangle_drawn(h.index)) as usize;
            }
        }
        assert!(severed_hits > 0, "no ray met a severed triangle");
    }
}
