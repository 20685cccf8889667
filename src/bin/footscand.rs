fn main() {
    println!("footscand {}", env!("CARGO_PKG_VERSION"));
}
