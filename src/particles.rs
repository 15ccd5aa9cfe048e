//! Per-particle constants and flags: mass, the inverse mass integration uses (zero for a
//! particle it must not move), pinned, alive.

/// Per-particle constants and flags.
#[derive(Clone, Debug)]
pub struct Particles {
    /// Mass in kg (kept for pinned and cut particles, so that unpinning restores it).
    pub mass: Vec<f32>,
    /// 1 / mass, or 0 for a particle that integration must not move (pinned or cut).
    pub inv_mass: Vec<f32>,
    pub pinned: Vec<bool>,
    /// False once a particle has been cut out of the cloth.
    pub alive: Vec<bool>,
}

impl Particles {
    pub fn new(n: usize, mass: f32) -> Self {
        Particles {
            mass: vec![mass; n],
            inv_mass: vec![1.0 / mass; n],
            pinned: vec![false; n],
            alive: vec![true; n],
        }
    }

    pub fn len(&self) -> usize {
        self.mass.len()
    }

    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// Whether integration and collisions move particle `p`.
    pub fn is_dynamic(&self, p: usize) -> bool {
        self.inv_mass[p] > 0.0
    }

    /// Pins or unpins particle `p` (its inverse mass follows).
    pub fn set_pinned(&mut self, p: usize, pinned: bool) {
        self.pinned[p] = pinned;
        self.refresh(p);
    }

    /// Sets particle `p`'s mass in kg.
    pub fn set_mass(&mut self, p: usize, mass: f32) {
        self.mass[p] = mass;
        self.refresh(p);
    }

    /// Marks particle `p` cut: neither alive nor pinned, and never moved again.
    pub fn cut(&mut self, p: usize) {
        self.alive[p] = false;
        self.pinned[p] = false;
        self.refresh(p);
    }

    /// Recomputes `inv_mass[p]` from the flags.
    pub fn refresh(&mut self, p: usize) {
        self.inv_mass[p] = if self.pinned[p] || !self.alive[p] {
            0.0
        } else {
            1.0 / self.mass[p]
        };
    }

    pub fn heap_bytes(&self) -> usize {
        (self.mass.capacity() + self.inv_mass.capacity()) * size_of::<f32>()
            + self.pinned.capacity()
            + self.alive.capacity()
    }
}
