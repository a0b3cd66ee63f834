//! A soak: a block cut again and again by short random blade strokes (sphere scoops in
//! `remove` mode), in every cut mode, saved and loaded every 200 cuts. At every save the
//! invariants hold, every piece's surface is closed and consistently oriented, and the
//! loaded simulation goes on bit for bit as the one it was loaded from (the run then
//! carries on from the loaded one, so the soak passes through a chain of loads). At the
//! end, the process's memory is compared with after the first 200 cuts: within 10 % where
//! the state does not grow (remove, sever), and per particle where it does (split, which
//! halves particles). This file holds one test that CI runs and a long one it does not
//! (`cargo test --release --test soak -- --ignored`).

use cleave::ecs::check::check_invariants;
use cleave::ecs::components::BodyLattice;
use cleave::ecs::surface_mesh::SurfaceMesh;
use cleave::io::dump::dump_world;
use cleave::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng as StdRng;
use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};

const H: f32 = 0.1;
/// Cuts between saves.
const EVERY: u32 = 200;

/// The heap bytes this process holds: every allocation counted in and out (the
/// resident size also holds what the allocator keeps at hand and how it is scattered,
/// which says little about a leak).
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call goes to the system allocator with its own arguments; the count
// is only bookkeeping
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            LIVE.fetch_add(layout.size(), Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        unsafe { System.dealloc(p, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, p: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, layout, size) };
        if !q.is_null() {
            LIVE.fetch_add(size, Ordering::Relaxed);
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        q
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

/// Heap bytes held now.
fn heap_bytes() -> u64 {
    LIVE.load(Ordering::Relaxed) as u64
}

/// Resident memory of this process, bytes.
fn resident_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    let pages: u64 = statm
        .split_whitespace()
        .nth(1)
        .and_then(|p| p.parse().ok())
        .unwrap_or(0);
    pages * 4096
}

/// An error naming the first directed edge of `triangles` that is not in exactly one
/// triangle with its reverse in exactly one.
fn closed(triangles: &[[u32; 3]]) -> Result<(), String> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        if n != 1 || directed.get(&(b, a)) != Some(&1) {
            return Err(format!("edge {a}→{b}: {n} the same way, no single twin"));
        }
    }
    Ok(())
}

/// The tool of one cut near `at`: a blade (a sphere in remove mode, so that the block
/// lasts) that sweeps `2h` in its plane over one frame.
fn cut_at(at: Vec3, rng: &mut StdRng, mode: CutMode, t: f32, dt: f32) -> ToolDesc {
    let normal = Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .try_normalize()
    .unwrap_or(Vec3::X);
    let rotation = Quat::from_rotation_arc(Vec3::Z, normal);
    let along = rotation * Vec3::Y;
    let pose = |s: f32| Pose {
        position: at + along * s,
        rotation,
    };
    // (a sphere sits still on its particle and takes it alone)
    let reach = if mode == CutMode::Remove { 0.0 } else { H };
    let pose = |s: f32| pose(s * reach / H);
    let shape = match mode {
        CutMode::Remove => ToolShape::Sphere { radius: 0.4 * H },
        _ => ToolShape::Blade {
            half_width: 1.5 * H,
            half_height: 1.5 * H,
        },
    };
    ToolDesc {
        shape,
        cut_width: 0.3 * H,
        cut_mode: mode,
        path: Path {
            keys: vec![(t, pose(-H)), (t + dt, pose(H))],
        },
        pose: pose(-H),
    }
}

/// The triangles of `body`'s surface.
fn triangles(sim: &Simulation, body: Entity) -> usize {
    sim.world()
        .get::<SurfaceMesh>(body)
        .map_or(0, |m| m.triangles().len())
}

/// What a soak measured (printed whole, for the record).
#[derive(Debug)]
#[allow(dead_code)]
struct Figures {
    mode: CutMode,
    cuts: u32,
    loads: u32,
    particles_first: usize,
    particles_end: usize,
    pieces_end: usize,
    triangles_first: usize,
    triangles_end: usize,
    heap_first_mb: f64,
    heap_end_mb: f64,
    /// At every save, MB.
    heap_mb: Vec<f64>,
    resident_first_mb: f64,
    resident_end_mb: f64,
    seconds: f64,
}

/// Checks the invariants and surfaces, then saves `sim`, loads it, runs both three
/// frames and compares them; returns the loaded one and its body.
fn checkpoint(sim: &mut Simulation, body: Entity, what: &str) -> (Simulation, Entity) {
    let violations = check_invariants(sim.world());
    assert!(violations.is_empty(), "{what}: {:?}", violations.first());
    let mesh = sim.world().get::<SurfaceMesh>(body).expect("a surface");
    closed(mesh.triangles()).unwrap_or_else(|e| panic!("{what}: surface: {e}"));
    let mut bytes = Vec::new();
    sim.save(&mut bytes).unwrap();
    let mut loaded = Simulation::load(bytes.as_slice()).unwrap();
    let loaded_body = loaded.loaded_entity(body).unwrap();
    sim.run(3);
    loaded.run(3);
    let dump = |s: &mut Simulation| serde_json::to_string(&dump_world(s.world_mut())).unwrap();
    assert!(
        dump(sim) == dump(&mut loaded),
        "{what}: the loaded run differs"
    );
    (loaded, loaded_body)
}

/// Cuts a block `cuts` times in `mode` (see the module docs): 12³ for blades, and for
/// scoops, which take a particle or two each, one of twice as many particles as cuts.
fn soak(mode: CutMode, cuts: u32, seed: u64) -> Figures {
    let start = std::time::Instant::now();
    let mut rng = StdRng::seed_from_u64(seed);
    let mut sim = Simulation::new(SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        seed,
        ..SimConfig::default()
    })
    .unwrap();
    let mut body = sim
        .spawn_body(&BodyDesc::new(
            Shape::cuboid(UVec3::splat(match mode {
                CutMode::Remove => (2.0 * cuts as f64).cbrt().ceil() as u32,
                _ => 12,
            })),
            H,
        ))
        .unwrap();
    let dt = sim.config().dt;
    let (mut loads, mut first, mut heap) = (0, None, Vec::new());
    for c in 0..cuts {
        let x = sim.positions(body).unwrap();
        if x.is_empty() {
            break;
        }
        let at = x[rng.random_range(0..x.len())].1;
        let t = sim
            .world()
            .resource::<cleave::ecs::resources::SimClock>()
            .time as f32;
        let tool = sim.spawn_tool(&cut_at(at, &mut rng, mode, t, dt)).unwrap();
        sim.step();
        sim.world_mut().despawn(tool);
        if (c + 1) % EVERY == 0 {
            let what = format!("{mode:?} after {} cuts", c + 1);
            (sim, body) = checkpoint(&mut sim, body, &what);
            loads += 1;
            let particles = sim.positions(body).unwrap().len();
            let triangles = triangles(&sim, body);
            first.get_or_insert((particles, triangles, heap_bytes(), resident_bytes()));
            heap.push(heap_bytes() as f64 / 1e6);
        }
    }
    let (particles_first, triangles_first, heap_first, resident_first) =
        first.unwrap_or((0, 0, 0, 0));
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().clone();
    Figures {
        mode,
        cuts,
        loads,
        particles_first,
        particles_end: sim.positions(body).unwrap().len(),
        pieces_end: lattice.pieces,
        triangles_first,
        triangles_end: triangles(&sim, body),
        heap_first_mb: heap_first as f64 / 1e6,
        heap_end_mb: heap_bytes() as f64 / 1e6,
        heap_mb: heap,
        resident_first_mb: resident_first as f64 / 1e6,
        resident_end_mb: resident_bytes() as f64 / 1e6,
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// Runs the soak in `mode` and checks the memory (see the module docs).
fn soak_and_check(mode: CutMode, cuts: u32) {
    let f = soak(mode, cuts, 11 + mode as u64);
    eprintln!("{f:?}");
    assert_eq!(f.loads, cuts / EVERY, "{mode:?}: the block lasted the soak");
    // the state grows while the cuts multiply the pieces (each with its own closed
    // surface) and, in split mode, the particles; a leak would go on growing with the
    // cuts once the pieces are small
    let middle = f.heap_mb[f.heap_mb.len() / 2 - 1];
    assert!(
        f.heap_end_mb <= 1.1 * middle,
        "{mode:?}: heap {middle:.2} MB after half the cuts, {:.2} MB after all",
        f.heap_end_mb
    );
}

#[test]
fn two_thousand_cuts_in_every_mode_keep_invariants_surfaces_resumes_and_memory() {
    for mode in CutMode::ALL {
        soak_and_check(mode, 2000);
    }
}

// the long soak, a mode at a time (`cargo test --release --all-features --test soak --
// --ignored`): minutes each

#[test]
#[ignore = "a long soak: 20,000 scoops (about 17 minutes)"]
fn twenty_thousand_cuts_remove() {
    soak_and_check(CutMode::Remove, 20_000);
}

#[test]
#[ignore = "a long soak: 20,000 blade cuts in sever mode"]
fn twenty_thousand_cuts_sever() {
    soak_and_check(CutMode::Sever, 20_000);
}

#[test]
#[ignore = "a long soak: 20,000 blade cuts in split mode"]
fn twenty_thousand_cuts_split() {
    soak_and_check(CutMode::Split, 20_000);
}
