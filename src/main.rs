use clap::Parser;
use facesynth::cli::Next;

fn main() -> std::process::ExitCode {
    let cli = facesynth::cli::Cli::parse();
    let outcome = facesynth::cli::run(cli).and_then(|next| match next {
        Next::Done => Ok(()),
        Next::View(args) => view(*args),
    });
    match outcome {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // One line: the library's errors already name the file and the problem.
            eprintln!("facesynth: error: {}", facesynth::cli::error_line(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The editor (`facesynth view`, `facesynth review DIR`, or no command).
#[cfg(feature = "gui")]
fn view(args: facesynth::view_options::ViewArgs) -> anyhow::Result<()> {
    facesynth::app::run(args)
}

#[cfg(not(feature = "gui"))]
fn view(_args: facesynth::view_options::ViewArgs) -> anyhow::Result<()> {
    anyhow::bail!("this facesynth was built without the `gui` feature; the editor is unavailable")
}
