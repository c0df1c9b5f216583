//! `blockwalk serve`: a tiled city's folder over HTTP with range requests, for `walk` and `view`
//! on other machines (any static server with range support does the same), or a `.3tz` tileset's
//! entries for CesiumJS and other 3D Tiles viewers.

use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The folder to serve (a tiled city: `jobs merge`'s output; a tileset folder), or a .3tz
    /// tileset (`tileset -o CITY.3tz`), whose entries are served by path through its index:
    /// viewers load http://ADDR/tileset.json. Answers allow any origin (CORS), so a web viewer
    /// served from elsewhere may load them.
    pub dir: PathBuf,
    /// Address to listen on (`0.0.0.0:8080` for every interface; port 0 picks a free one).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub addr: String,
    /// Connections served at once, each on a thread of its own (more wait to be accepted; a
    /// connection idle for 2 s is closed).
    #[arg(long, alias = "threads", default_value_t = 64)]
    pub connections: usize,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let server = blockwalk::stream::serve::Server::start(&args.dir, &args.addr, args.connections)
        .map_err(anyhow::Error::msg)?;
    let index = if args.dir.join("index.json").is_file() {
        "index.json"
    } else if args.dir.is_file() || args.dir.join("tileset.json").is_file() {
        "tileset.json"
    } else {
        ""
    };
    outln!(
        "serving {} at {}{index} (Ctrl-C stops)",
        args.dir.display(),
        server.url(),
    );
    loop {
        std::thread::park();
    }
}
