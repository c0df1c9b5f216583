//! `blockwalk serve`: a tiled city's folder over HTTP with range requests, for `walk` and `view`
//! on other machines (any static server with range support does the same).

use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The folder to serve (a tiled city: `jobs merge`'s output).
    pub dir: PathBuf,
    /// Address to listen on (`0.0.0.0:8080` for every interface; port 0 picks a free one).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub addr: String,
    /// Threads answering requests.
    #[arg(long, default_value_t = 8)]
    pub threads: usize,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let server = blockwalk::stream::serve::Server::start(&args.dir, &args.addr, args.threads)
        .map_err(anyhow::Error::msg)?;
    let index = args.dir.join("index.json").is_file();
    outln!(
        "serving {} at {}{} (Ctrl-C stops)",
        args.dir.display(),
        server.url(),
        if index { "index.json" } else { "" }
    );
    loop {
        std::thread::park();
    }
}
