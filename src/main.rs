fn main() {
    match tetvr::gpu::GpuContext::new(tetvr::gpu::AdapterChoice::Auto) {
        Ok(c) => println!("{}", c.report()),
        Err(e) => eprintln!("{e}"),
    }
}
