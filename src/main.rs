use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = facesynth::cli::Cli::parse();
    match facesynth::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // One line: the library's errors already name the file and the problem.
            eprintln!("facesynth: error: {}", facesynth::cli::error_line(&e));
            std::process::ExitCode::FAILURE
        }
    }
}
