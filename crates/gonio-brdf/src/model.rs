use gonio_core::{Channels, Dir};

use crate::Brdf;
use crate::models::{BlinnPhong, CookTorrance, Diffuse, Lafortune, OrenNayar, Phong, Ward};
use crate::proposal::Weighted;

/// The kinds of model a model file can name (`kind = "…"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModelKind {
    /// `lambert`: [`Diffuse`] with `n = 0`.
    Lambert,
    /// `minnaert`: [`Diffuse`] (Lafortune et al. Eq. 6).
    Minnaert,
    /// `phong`: [`Phong`].
    Phong,
    /// `blinn-phong`: [`BlinnPhong`].
    BlinnPhong,
    /// `ward`: [`Ward`].
    Ward,
    /// `cook-torrance`: [`CookTorrance`].
    CookTorrance,
    /// `oren-nayar`: [`OrenNayar`].
    OrenNayar,
    /// `lafortune`: [`Lafortune`].
    Lafortune,
}

impl ModelKind {
    /// Every kind, in the order of `docs/CONVENTIONS.md`.
    pub const ALL: [ModelKind; 8] = [
        ModelKind::Lambert,
        ModelKind::Phong,
        ModelKind::BlinnPhong,
        ModelKind::Ward,
        ModelKind::CookTorrance,
        ModelKind::Lafortune,
        ModelKind::Minnaert,
        ModelKind::OrenNayar,
    ];

    /// The name used in model files.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Lambert => "lambert",
            ModelKind::Minnaert => "minnaert",
            ModelKind::Phong => "phong",
            ModelKind::BlinnPhong => "blinn-phong",
            ModelKind::Ward => "ward",
            ModelKind::CookTorrance => "cook-torrance",
            ModelKind::OrenNayar => "oren-nayar",
            ModelKind::Lafortune => "lafortune",
        }
    }

    /// The kind named `name` in a model file.
    pub fn from_name(name: &str) -> Option<ModelKind> {
        ModelKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// Any analytic model: what a model file holds.
#[derive(Clone, Debug, PartialEq)]
pub enum Model {
    /// Lambert.
    Lambert(Diffuse),
    /// Minnaert.
    Minnaert(Diffuse),
    /// Cosine lobe / Phong.
    Phong(Phong),
    /// Blinn-Phong.
    BlinnPhong(BlinnPhong),
    /// Ward.
    Ward(Ward),
    /// Cook–Torrance.
    CookTorrance(CookTorrance),
    /// Oren–Nayar.
    OrenNayar(OrenNayar),
    /// Lafortune generalized cosine lobes.
    Lafortune(Lafortune),
}

impl Model {
    /// The model's kind.
    pub fn kind(&self) -> ModelKind {
        match self {
            Model::Lambert(_) => ModelKind::Lambert,
            Model::Minnaert(_) => ModelKind::Minnaert,
            Model::Phong(_) => ModelKind::Phong,
            Model::BlinnPhong(_) => ModelKind::BlinnPhong,
            Model::Ward(_) => ModelKind::Ward,
            Model::CookTorrance(_) => ModelKind::CookTorrance,
            Model::OrenNayar(_) => ModelKind::OrenNayar,
            Model::Lafortune(_) => ModelKind::Lafortune,
        }
    }

    /// The model as a trait object.
    pub fn as_brdf(&self) -> &dyn Brdf {
        match self {
            Model::Lambert(m) | Model::Minnaert(m) => m,
            Model::Phong(m) => m,
            Model::BlinnPhong(m) => m,
            Model::Ward(m) => m,
            Model::CookTorrance(m) => m,
            Model::OrenNayar(m) => m,
            Model::Lafortune(m) => m,
        }
    }
}

impl Brdf for Model {
    fn channels(&self) -> &Channels {
        self.as_brdf().channels()
    }
    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        self.as_brdf().eval(wi, wo, out)
    }
    fn proposals(&self, wi: Dir, out: &mut Vec<Weighted>) {
        self.as_brdf().proposals(wi, out)
    }
    fn mirror(&self, wi: Dir, out: &mut [f64]) -> bool {
        self.as_brdf().mirror(wi, out)
    }
    fn is_reciprocal(&self) -> bool {
        self.as_brdf().is_reciprocal()
    }
    fn albedo(&self, wi: Dir, out: &mut [f64]) {
        self.as_brdf().albedo(wi, out)
    }
    fn sample(&self, wi: Dir, uc: f64, u: [f64; 2]) -> Option<crate::BrdfSample> {
        self.as_brdf().sample(wi, uc, u)
    }
    fn pdf(&self, wi: Dir, wo: Dir) -> f64 {
        self.as_brdf().pdf(wi, wo)
    }
}
