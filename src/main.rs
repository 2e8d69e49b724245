fn main() {
    eprintln!("tactus: not built yet");
    std::process::exit(2);
}
