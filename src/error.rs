//! The library's error type: every typed error of the library's modules in
//! one enum, for callers that want a single `Result`. Messages name the
//! problem (the file, the value); command-line flag names are added by the
//! `npf` program, never here.

/// Any error of the npf library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or writing a measured table or a file.
    #[error(transparent)]
    Load(#[from] npf_data_loaders::LoadError),
    /// Reading or writing a model file.
    #[error(transparent)]
    ModelFile(#[from] crate::modelfile::ModelFileError),
    /// Building a fit set from samples.
    #[error(transparent)]
    Sample(#[from] crate::samples::SampleError),
    /// Setting up or running a fit.
    #[error(transparent)]
    Fit(#[from] crate::fit::FitError),
    /// The solver refused its options or start.
    #[error(transparent)]
    Solver(#[from] crate::solver::SolverError),
    /// A model that breaks its layout's rules.
    #[error(transparent)]
    Model(#[from] crate::model::ModelError),
    /// A model that cannot be turned into a sampler.
    #[error(transparent)]
    Bsdf(#[from] crate::bsdf::BsdfError),
    /// An evaluation against a reference failed.
    #[error(transparent)]
    Eval(#[from] crate::evaluation::EvalError),
    /// Two renders could not be compared.
    #[error(transparent)]
    Render(#[from] crate::render::RenderError),
    /// The GGX baseline fit failed.
    #[error(transparent)]
    Ggx(#[from] crate::baselines::GgxFitError),
    /// A shader or C export that could not be written.
    #[error(transparent)]
    Shader(#[from] crate::export::shader::ShaderError),
}

/// `Result` with the library's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
