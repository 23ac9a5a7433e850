//! Model files: the TOML of `docs/CONVENTIONS.md`, read strictly (unknown keys are errors,
//! every list has one value a channel) with errors that name file, line and field.
//!
//! Parameter names per kind are documented in `docs/models.md`.

use std::fmt;
use std::fmt::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};

use gonio_core::Channels;
use serde::Deserialize;
use toml::Spanned;

use crate::model::{Model, ModelKind};
use crate::models::{
    BlinnPhong, CookTorrance, Diffuse, Distribution, FitNote, Lafortune, LafortuneLobe, Mirror,
    OrenNayar, OrenNayarVariant, ParamError, Phong, PhongNormalization, Sym3, Ward,
};

/// What kind of failure a [`ModelError`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelErrorKind {
    /// The file could not be read.
    Io,
    /// Not valid TOML, an unknown key, or a value of the wrong type.
    Syntax,
    /// Valid TOML with a parameter that is missing, out of range or of the wrong length.
    Invalid,
}

/// A model file that could not be read, with where and why.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelError {
    /// The file, when known.
    pub path: Option<PathBuf>,
    /// 1-based line, when the fault has a place.
    pub line: Option<usize>,
    /// 1-based column (in characters), when the fault has a place.
    pub column: Option<usize>,
    /// The field at fault (`lobes[1].cz`), when there is one.
    pub field: Option<String>,
    /// The kind of failure.
    pub kind: ModelErrorKind,
    /// What is wrong.
    pub message: String,
}

impl ModelError {
    pub(crate) fn io(path: &Path, e: &gonio_core::input::InputError) -> Self {
        ModelError {
            path: Some(path.to_path_buf()),
            line: None,
            column: None,
            field: None,
            kind: ModelErrorKind::Io,
            message: e.reason(),
        }
    }
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        gonio_core::text::write_located(
            f,
            self.path.as_deref(),
            "<model>",
            self.line,
            self.column,
            self.field.as_deref(),
            &self.message,
        )
    }
}

impl std::error::Error for ModelError {}

type S<T> = Spanned<T>;
type Span = Range<usize>;

struct Ctx<'a> {
    text: &'a str,
    path: Option<&'a Path>,
}

impl Ctx<'_> {
    fn error(
        &self,
        span: Option<Span>,
        field: Option<String>,
        kind: ModelErrorKind,
        message: impl Into<String>,
    ) -> ModelError {
        let (line, column) = match span {
            Some(s) => {
                let (l, c) = gonio_core::text::line_col(self.text, s.start);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        ModelError {
            path: self.path.map(Path::to_path_buf),
            line,
            column,
            field,
            kind,
            message: message.into(),
        }
    }

    fn syntax(&self, e: toml::de::Error) -> ModelError {
        let f = gonio_core::tomlfile::Fault::of(self.text, &e);
        self.error(f.span, f.field, ModelErrorKind::Syntax, f.message)
    }

    fn invalid(&self, span: Span, field: &str, message: impl Into<String>) -> ModelError {
        self.error(
            Some(span),
            Some(field.to_string()),
            ModelErrorKind::Invalid,
            message,
        )
    }

    /// Places a constructor's [`ParamError`] at the span of the field it names.
    fn param(&self, mut e: ParamError, spans: &[(String, Span)], fallback: Span) -> ModelError {
        // An isotropic `alpha` is both `alpha_x` and `alpha_y` to the constructors: the
        // error names the key the file has.
        if (e.field == "alpha_x" || e.field == "alpha_y") && spans.iter().any(|(f, _)| f == "alpha")
        {
            e.field = "alpha".into();
        }
        let span = spans
            .iter()
            .find(|(f, _)| *f == e.field)
            .map_or(fallback, |(_, s)| s.clone());
        self.invalid(span, &e.field, e.message)
    }

    fn channels(&self, c: &S<Vec<String>>) -> Result<Channels, ModelError> {
        Channels::from_names(c.get_ref())
            .map_err(|e| self.invalid(c.span(), "channels", e.to_string()))
    }

    fn de<'de, T: Deserialize<'de>>(&self, text: &'de str) -> Result<T, ModelError> {
        toml::from_str(text).map_err(|e| self.syntax(e))
    }
}

fn sp(name: impl Into<String>, v: &S<impl Sized>) -> (String, Span) {
    (name.into(), v.span())
}

#[derive(Deserialize)]
struct Head {
    kind: Option<S<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DiffuseFile {
    rho: S<Vec<f64>>,
    n: Option<S<Vec<f64>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MirrorFile {
    rm: S<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LambertFile {
    #[allow(dead_code)]
    kind: String,
    channels: S<Vec<String>>,
    rho: S<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MinnaertFile {
    #[allow(dead_code)]
    kind: String,
    channels: S<Vec<String>>,
    rho: S<Vec<f64>>,
    n: S<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PhongFile {
    #[allow(dead_code)]
    kind: String,
    channels: S<Vec<String>>,
    rho_s: S<Vec<f64>>,
    n: S<Vec<f64>>,
    normalization: Option<S<String>>,
    shading: Option<bool>,
    diffuse: Option<S<DiffuseFile>>,
    mirror: Option<S<MirrorFile>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BlinnPhongFile {
    #[allow(dead_code)]
    kind: String,
    channels: S<Vec<String>>,
    rho_s: S<Vec<f64>>,
    n: S<Vec<f64>>,
    diffuse: Option<S<DiffuseFile>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WardFile {
    #[allow(dead_code)]
    kind: String,
    channels: S<Vec<String>>,
    rho_s: S<Vec<f64>>,
    alpha: Option<S<Vec<f64>>>,
    alpha_x: Option<S<Vec<f64>>>,
    alpha_y: Option<S<Vec<f64>>>,
    diffuse: Option<S<DiffuseFile>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CookTorranceFile {
    #[allow(dead_code)]
    kind: String,
    channels: S<Vec<String>>,
    distribution: S<String>,
    f0: S<Vec<f64>>,
    alpha: Option<S<Vec<f64>>>,
    alpha_x: Option<S<Vec<f64>>>,
    alpha_y: Option<S<Vec<f64>>>,
    rho_s: Option<S<Vec<f64>>>,
    diffuse: Option<S<DiffuseFile>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OrenNayarFile {
    #[allow(dead_code)]
    kind: String,
    channels: S<Vec<String>>,
    rho: S<Vec<f64>>,
    sigma_deg: S<Vec<f64>>,
    variant: Option<S<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LobeFile {
    cx: Option<S<Vec<f64>>>,
    cy: Option<S<Vec<f64>>>,
    cz: Option<S<Vec<f64>>>,
    m: Option<S<Vec<[[f64; 3]; 3]>>>,
    n: S<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LafortuneFile {
    #[allow(dead_code)]
    kind: String,
    channels: S<Vec<String>>,
    #[serde(default)]
    lobes: Vec<S<LobeFile>>,
    diffuse: Option<S<DiffuseFile>>,
    mirror: Option<S<MirrorFile>>,
    fit: Option<FitNoteFile>,
}

/// The optional `[fit]` table of a fitted lafortune model (what `gonio fit` minimised).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FitNoteFile {
    objective: String,
    minimised: String,
    constraint: Option<String>,
}

/// The `[diffuse]` table, with its span for errors about the term as a whole.
fn diffuse(
    ctx: &Ctx,
    ch: &Channels,
    d: &Option<S<DiffuseFile>>,
) -> Result<Option<(Diffuse, Span)>, ModelError> {
    let Some(d) = d else { return Ok(None) };
    let spans = [
        sp("diffuse.rho", &d.get_ref().rho),
        d.get_ref()
            .n
            .as_ref()
            .map_or_else(|| ("diffuse.n".into(), d.span()), |n| sp("diffuse.n", n)),
    ];
    let f = d.get_ref();
    let rho = f.rho.get_ref().clone();
    let made = match &f.n {
        None => Diffuse::lambert(ch.clone(), rho),
        Some(n) => Diffuse::minnaert(ch.clone(), rho, n.get_ref().clone()),
    };
    made.map(|m| Some((m, d.span())))
        .map_err(|e| ctx.param(e.within("diffuse"), &spans, d.span()))
}

/// The `[mirror]` table, with its span for errors about the term as a whole.
fn mirror(
    ctx: &Ctx,
    ch: &Channels,
    m: &Option<S<MirrorFile>>,
) -> Result<Option<(Mirror, Span)>, ModelError> {
    let Some(m) = m else { return Ok(None) };
    let spans = [sp("mirror.rm", &m.get_ref().rm)];
    Mirror::new(ch, m.get_ref().rm.get_ref().clone())
        .map(|r| Some((r, m.span())))
        .map_err(|e| ctx.param(e.within("mirror"), &spans, m.span()))
}

/// `alpha` alone (isotropic) or `alpha_x` with `alpha_y`.
#[allow(clippy::type_complexity)]
fn roughness(
    ctx: &Ctx,
    alpha: &Option<S<Vec<f64>>>,
    ax: &Option<S<Vec<f64>>>,
    ay: &Option<S<Vec<f64>>>,
    whole: Span,
) -> Result<(Vec<f64>, Vec<f64>, Vec<(String, Span)>), ModelError> {
    match (alpha, ax, ay) {
        (Some(a), None, None) => Ok((
            a.get_ref().clone(),
            a.get_ref().clone(),
            vec![sp("alpha_x", a), sp("alpha_y", a), sp("alpha", a)],
        )),
        (None, Some(x), Some(y)) => Ok((
            x.get_ref().clone(),
            y.get_ref().clone(),
            vec![sp("alpha_x", x), sp("alpha_y", y)],
        )),
        (Some(a), _, _) => Err(ctx.invalid(
            a.span(),
            "alpha",
            "give either `alpha` (isotropic) or both `alpha_x` and `alpha_y`, not both forms",
        )),
        (None, Some(x), None) => Err(ctx.invalid(
            x.span(),
            "alpha_y",
            "`alpha_x` needs `alpha_y` (or give one isotropic `alpha`)",
        )),
        (None, None, Some(y)) => Err(ctx.invalid(
            y.span(),
            "alpha_x",
            "`alpha_y` needs `alpha_x` (or give one isotropic `alpha`)",
        )),
        _ => Err(ctx.invalid(
            whole,
            "alpha",
            "missing roughness: give `alpha` (isotropic) or both `alpha_x` and `alpha_y`",
        )),
    }
}

fn choice<T: Copy>(
    ctx: &Ctx,
    field: &str,
    value: &Option<S<String>>,
    default: T,
    options: &[(&str, T)],
) -> Result<T, ModelError> {
    let Some(v) = value else { return Ok(default) };
    options
        .iter()
        .find(|(n, _)| *n == v.get_ref())
        .map(|(_, t)| *t)
        .ok_or_else(|| {
            let names: Vec<_> = options.iter().map(|(n, _)| format!("\"{n}\"")).collect();
            ctx.invalid(
                v.span(),
                field,
                format!("{:?} is not one of {}", v.get_ref(), names.join(", ")),
            )
        })
}

fn lobe(ctx: &Ctx, ch: &Channels, i: usize, l: &S<LobeFile>) -> Result<LafortuneLobe, ModelError> {
    let f = l.get_ref();
    let at = |k: &str| format!("lobes[{i}].{k}");
    let mut spans = vec![sp(at("n"), &f.n)];
    let made = match (&f.m, &f.cx, &f.cz) {
        (Some(m), None, None) if f.cy.is_none() => {
            spans.push(sp(at("m"), m));
            let mut mats = Vec::with_capacity(m.get_ref().len());
            for (c, rows) in m.get_ref().iter().enumerate() {
                let s = Sym3::from_rows(*rows).ok_or_else(|| {
                    ctx.invalid(
                        m.span(),
                        &at("m"),
                        format!(
                            "matrix for channel {} is not symmetric (Eq. 3 needs M = Mᵀ for reciprocity)",
                            if c < ch.len() { ch.name(c) } else { c.to_string() }
                        ),
                    )
                })?;
                mats.push(s);
            }
            LafortuneLobe::from_matrices(ch, mats, f.n.get_ref().clone())
        }
        (None, Some(cx), Some(cz)) => {
            spans.push(sp(at("cx"), cx));
            spans.push(sp(at("cz"), cz));
            // Cy defaults to Cx: the isotropic lobe.
            let cy = f.cy.as_ref().unwrap_or(cx);
            spans.push(sp(at("cy"), cy));
            LafortuneLobe::diagonal(ch, cx.get_ref(), cy.get_ref(), cz.get_ref(), f.n.get_ref())
        }
        _ => {
            return Err(ctx.invalid(
                l.span(),
                &format!("lobes[{i}]"),
                "a lobe needs either `cx`, `cz` (and optionally `cy`, default `cx`) and `n` (Eq. 4), or a matrix `m` and `n` (Eq. 3)",
            ));
        }
    };
    made.map_err(|e| ctx.param(e.within(&format!("lobes[{i}]")), &spans, l.span()))
}

pub(crate) fn parse(text: &str, path: Option<&Path>) -> Result<Model, ModelError> {
    let text = gonio_core::text::strip_bom(text);
    let ctx = Ctx { text, path };
    let head: Head = ctx.de(text)?;
    let Some(kind) = head.kind else {
        return Err(ctx.error(
            None,
            Some("kind".into()),
            ModelErrorKind::Invalid,
            "missing `kind` (one of lambert, phong, blinn-phong, ward, cook-torrance, lafortune, minnaert, oren-nayar)",
        ));
    };
    let Some(k) = ModelKind::from_name(kind.get_ref()) else {
        let names: Vec<_> = ModelKind::ALL.iter().map(|k| k.name()).collect();
        return Err(ctx.invalid(
            kind.span(),
            "kind",
            format!(
                "unknown kind {:?} (expected one of {})",
                kind.get_ref(),
                names.join(", ")
            ),
        ));
    };
    let all = 0..text.len();
    Ok(match k {
        ModelKind::Lambert => {
            let f: LambertFile = ctx.de(text)?;
            let ch = ctx.channels(&f.channels)?;
            let spans = [sp("rho", &f.rho)];
            Model::Lambert(
                Diffuse::lambert(ch, f.rho.into_inner()).map_err(|e| ctx.param(e, &spans, all))?,
            )
        }
        ModelKind::Minnaert => {
            let f: MinnaertFile = ctx.de(text)?;
            let ch = ctx.channels(&f.channels)?;
            let spans = [sp("rho", &f.rho), sp("n", &f.n)];
            Model::Minnaert(
                Diffuse::minnaert(ch, f.rho.into_inner(), f.n.into_inner())
                    .map_err(|e| ctx.param(e, &spans, all))?,
            )
        }
        ModelKind::Phong => phong(&ctx)?,
        ModelKind::BlinnPhong => blinn_phong(&ctx)?,
        ModelKind::Ward => ward(&ctx)?,
        ModelKind::CookTorrance => cook_torrance(&ctx)?,
        ModelKind::OrenNayar => oren_nayar(&ctx)?,
        ModelKind::Lafortune => lafortune(&ctx)?,
    })
}

/// Phong: its normalisation (albedo unless given), a diffuse and a mirror term.
fn phong(ctx: &Ctx<'_>) -> Result<Model, ModelError> {
    let all = 0..ctx.text.len();
    let f: PhongFile = ctx.de(ctx.text)?;
    let ch = ctx.channels(&f.channels)?;
    let norm = choice(
        ctx,
        "normalization",
        &f.normalization,
        PhongNormalization::Albedo,
        &[
            ("albedo", PhongNormalization::Albedo),
            ("power", PhongNormalization::Power),
        ],
    )?;
    let spans = [sp("rho_s", &f.rho_s), sp("n", &f.n)];
    let mut m = Phong::new(
        ch.clone(),
        f.rho_s.get_ref().clone(),
        f.n.get_ref().clone(),
        norm,
        f.shading.unwrap_or(false),
    )
    .map_err(|e| ctx.param(e, &spans, all))?;
    if let Some((d, span)) = diffuse(ctx, &ch, &f.diffuse)? {
        m = m.with_diffuse(d).map_err(|e| ctx.param(e, &[], span))?;
    }
    if let Some((r, span)) = mirror(ctx, &ch, &f.mirror)? {
        m = m.with_mirror(r).map_err(|e| ctx.param(e, &[], span))?;
    }
    Ok(Model::Phong(m))
}

/// Blinn–Phong, with a diffuse term.
fn blinn_phong(ctx: &Ctx<'_>) -> Result<Model, ModelError> {
    let all = 0..ctx.text.len();
    let f: BlinnPhongFile = ctx.de(ctx.text)?;
    let ch = ctx.channels(&f.channels)?;
    let spans = [sp("rho_s", &f.rho_s), sp("n", &f.n)];
    let mut m = BlinnPhong::new(ch.clone(), f.rho_s.get_ref().clone(), f.n.get_ref().clone())
        .map_err(|e| ctx.param(e, &spans, all))?;
    if let Some((d, span)) = diffuse(ctx, &ch, &f.diffuse)? {
        m = m.with_diffuse(d).map_err(|e| ctx.param(e, &[], span))?;
    }
    Ok(Model::BlinnPhong(m))
}

/// Ward: isotropic or anisotropic roughness, with a diffuse term.
fn ward(ctx: &Ctx<'_>) -> Result<Model, ModelError> {
    let all = 0..ctx.text.len();
    let f: WardFile = ctx.de(ctx.text)?;
    let ch = ctx.channels(&f.channels)?;
    let (ax, ay, mut spans) = roughness(ctx, &f.alpha, &f.alpha_x, &f.alpha_y, all.clone())?;
    spans.push(sp("rho_s", &f.rho_s));
    let mut m = Ward::new(ch.clone(), f.rho_s.get_ref().clone(), ax, ay)
        .map_err(|e| ctx.param(e, &spans, all))?;
    if let Some((d, span)) = diffuse(ctx, &ch, &f.diffuse)? {
        m = m.with_diffuse(d).map_err(|e| ctx.param(e, &[], span))?;
    }
    Ok(Model::Ward(m))
}

/// Cook–Torrance: its distribution (GGX unless given), roughness, Fresnel
/// reflectance at normal incidence and specular scale (1 unless given), with a diffuse
/// term.
fn cook_torrance(ctx: &Ctx<'_>) -> Result<Model, ModelError> {
    let all = 0..ctx.text.len();
    let f: CookTorranceFile = ctx.de(ctx.text)?;
    let ch = ctx.channels(&f.channels)?;
    let dist = choice(
        ctx,
        "distribution",
        &Some(f.distribution.clone()),
        Distribution::Ggx,
        &[
            ("beckmann", Distribution::Beckmann),
            ("ggx", Distribution::Ggx),
        ],
    )?;
    let (ax, ay, mut spans) = roughness(ctx, &f.alpha, &f.alpha_x, &f.alpha_y, all.clone())?;
    spans.push(sp("f0", &f.f0));
    let rho_s = match &f.rho_s {
        Some(r) => {
            spans.push(sp("rho_s", r));
            r.get_ref().clone()
        }
        None => vec![1.0; ch.len()],
    };
    let mut m = CookTorrance::new(ch.clone(), dist, f.f0.get_ref().clone(), ax, ay, rho_s)
        .map_err(|e| ctx.param(e, &spans, all))?;
    if let Some((d, span)) = diffuse(ctx, &ch, &f.diffuse)? {
        m = m.with_diffuse(d).map_err(|e| ctx.param(e, &[], span))?;
    }
    Ok(Model::CookTorrance(m))
}

/// Oren–Nayar, full unless the qualitative variant is named.
fn oren_nayar(ctx: &Ctx<'_>) -> Result<Model, ModelError> {
    let all = 0..ctx.text.len();
    let f: OrenNayarFile = ctx.de(ctx.text)?;
    let ch = ctx.channels(&f.channels)?;
    let variant = choice(
        ctx,
        "variant",
        &f.variant,
        OrenNayarVariant::Full,
        &[
            ("full", OrenNayarVariant::Full),
            ("qualitative", OrenNayarVariant::Qualitative),
        ],
    )?;
    let spans = [sp("rho", &f.rho), sp("sigma_deg", &f.sigma_deg)];
    Ok(Model::OrenNayar(
        OrenNayar::new(ch, f.rho.into_inner(), f.sigma_deg.into_inner(), variant)
            .map_err(|e| ctx.param(e, &spans, all))?,
    ))
}

/// Lafortune: its lobes, a diffuse and a mirror term, and the note of the fit that
/// made it.
fn lafortune(ctx: &Ctx<'_>) -> Result<Model, ModelError> {
    let all = 0..ctx.text.len();
    let f: LafortuneFile = ctx.de(ctx.text)?;
    let ch = ctx.channels(&f.channels)?;
    let lobes = f
        .lobes
        .iter()
        .enumerate()
        .map(|(i, l)| lobe(ctx, &ch, i, l))
        .collect::<Result<Vec<_>, _>>()?;
    let mut m = Lafortune::new(ch.clone(), lobes).map_err(|e| ctx.param(e, &[], all.clone()))?;
    if let Some((d, span)) = diffuse(ctx, &ch, &f.diffuse)? {
        m = m.with_diffuse(d).map_err(|e| ctx.param(e, &[], span))?;
    }
    if let Some((r, span)) = mirror(ctx, &ch, &f.mirror)? {
        m = m.with_mirror(r).map_err(|e| ctx.param(e, &[], span))?;
    }
    if let Some(n) = f.fit {
        m = m.with_fit_note(FitNote {
            objective: n.objective,
            minimised: n.minimised,
            constraint: n.constraint,
        });
    }
    Ok(Model::Lafortune(m))
}

/// A TOML array of numbers, each in the shortest form that reads back exactly.
fn list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", items.join(", "))
}

fn write_diffuse(s: &mut String, d: Option<&Diffuse>) {
    if let Some(d) = d {
        let _ = writeln!(s, "\n[diffuse]\nrho = {}", list(d.rho()));
        if !d.is_lambert() {
            let _ = writeln!(s, "n = {}", list(d.n()));
        }
    }
}

fn write_mirror(s: &mut String, m: Option<&Mirror>) {
    if let Some(m) = m {
        let _ = writeln!(s, "\n[mirror]\nrm = {}", list(m.rm()));
    }
}

pub(crate) fn write(model: &Model) -> String {
    use crate::Brdf;
    let mut s = String::new();
    let ch = model.channels();
    let names: Vec<String> = ch.names().iter().map(|n| format!("{n:?}")).collect();
    let _ = writeln!(
        s,
        "kind = {:?}\nchannels = [{}]",
        model.kind().name(),
        names.join(", ")
    );
    match model {
        Model::Lambert(d) => {
            let _ = writeln!(s, "rho = {}", list(d.rho()));
        }
        Model::Minnaert(d) => {
            let _ = writeln!(s, "rho = {}\nn = {}", list(d.rho()), list(d.n()));
        }
        Model::Phong(p) => {
            let _ = writeln!(s, "rho_s = {}\nn = {}", list(p.rho_s()), list(p.n()));
            let _ = writeln!(s, "normalization = {:?}", p.normalization().name());
            if p.shading() {
                let _ = writeln!(s, "shading = true");
            }
            write_diffuse(&mut s, p.diffuse());
            write_mirror(&mut s, p.mirror_term());
        }
        Model::BlinnPhong(b) => {
            let _ = writeln!(s, "rho_s = {}\nn = {}", list(b.rho_s()), list(b.n()));
            write_diffuse(&mut s, b.diffuse());
        }
        Model::Ward(w) => {
            let _ = writeln!(s, "rho_s = {}", list(w.rho_s()));
            write_alpha(&mut s, w.alpha_x(), w.alpha_y());
            write_diffuse(&mut s, w.diffuse());
        }
        Model::CookTorrance(c) => {
            let _ = writeln!(s, "distribution = {:?}", c.distribution().name());
            let _ = writeln!(s, "f0 = {}", list(c.f0()));
            write_alpha(&mut s, c.alpha_x(), c.alpha_y());
            if c.rho_s().iter().any(|r| *r != 1.0) {
                let _ = writeln!(s, "rho_s = {}", list(c.rho_s()));
            }
            write_diffuse(&mut s, c.diffuse());
        }
        Model::OrenNayar(o) => {
            let _ = writeln!(
                s,
                "rho = {}\nsigma_deg = {}",
                list(o.rho()),
                list(o.sigma_deg())
            );
            let _ = writeln!(s, "variant = {:?}", o.variant().name());
        }
        Model::Lafortune(l) => {
            write_diffuse(&mut s, l.diffuse());
            write_mirror(&mut s, l.mirror_term());
            for lobe in l.lobes() {
                let _ = writeln!(s, "\n[[lobes]]");
                if lobe.is_diagonal() {
                    let m = lobe.matrices();
                    let col = |f: fn(&Sym3) -> f64| m.iter().map(f).collect::<Vec<_>>();
                    let _ = writeln!(s, "cx = {}", list(&col(|m| m.xx)));
                    let _ = writeln!(s, "cy = {}", list(&col(|m| m.yy)));
                    let _ = writeln!(s, "cz = {}", list(&col(|m| m.zz)));
                } else {
                    let mats: Vec<String> = lobe
                        .matrices()
                        .iter()
                        .map(|m| {
                            let rows: Vec<String> = m.rows().iter().map(|r| list(r)).collect();
                            format!("[{}]", rows.join(", "))
                        })
                        .collect();
                    let _ = writeln!(s, "m = [{}]", mats.join(", "));
                }
                let _ = writeln!(s, "n = {}", list(lobe.n()));
            }
            if let Some(n) = l.fit_note() {
                // Debug formatting quotes and escapes a string as TOML reads it.
                let _ = writeln!(
                    s,
                    "\n[fit]\nobjective = {:?}\nminimised = {:?}",
                    n.objective, n.minimised
                );
                if let Some(c) = &n.constraint {
                    let _ = writeln!(s, "constraint = {c:?}");
                }
            }
        }
    }
    s
}

fn write_alpha(s: &mut String, ax: &[f64], ay: &[f64]) {
    if ax == ay {
        let _ = writeln!(s, "alpha = {}", list(ax));
    } else {
        let _ = writeln!(s, "alpha_x = {}\nalpha_y = {}", list(ax), list(ay));
    }
}

/// Model files: a [`Model`] to and from its TOML text.
impl Model {
    /// Parses a model file's text; `path` only labels errors.
    pub fn from_toml(text: &str, path: Option<&Path>) -> Result<Model, ModelError> {
        parse(text, path)
    }

    /// Reads and parses a model file: a regular file of at most
    /// [`MAX_CONFIG_BYTES`](gonio_core::input::MAX_CONFIG_BYTES) (a FIFO, a device or
    /// a directory is refused without being read).
    pub fn load(path: &Path) -> Result<Model, ModelError> {
        let text = gonio_core::input::read_text(path, gonio_core::input::MAX_CONFIG_BYTES)
            .map_err(|e| ModelError::io(path, &e))?;
        Self::from_toml(&text, Some(path))
    }

    /// The model as a model file that [`from_toml`](Self::from_toml) reads back to an
    /// equal model.
    pub fn to_toml(&self) -> String {
        write(self)
    }
}
