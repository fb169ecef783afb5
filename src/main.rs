fn main() {
    println!("facesynth");
}
