//! Evaluation and sampling throughput of every material model.
//!
//! `cargo bench -p isolux-materials --bench throughput`; each iteration
//! evaluates (or samples) one of 256 precomputed direction pairs, so the
//! numbers are per call. Results are summarized in docs/benchmarks.md.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use isolux_core::{sampling, Pcg32, Rgb};
use isolux_materials::cook_torrance::{Masking, NormalDistribution};
use isolux_materials::metals::Metal;
use isolux_materials::microfacet::{Kind, Microfacet};
use isolux_materials::{
    Beckmann, BlinnPhong, BxdfModel, Conductor, CookTorrance, Dielectric, Diffuse, Fresnel,
    Gaussian, Ggx, HeidrichSeidel, Material, Mix, Phong, Plastic, Ward,
};

fn models() -> Vec<(&'static str, Material)> {
    let (eta, k) = Metal::by_name("Au").unwrap().rgb();
    let gold = Fresnel::Conductor {
        eta: Rgb::from_array(eta),
        k: Rgb::from_array(k),
    };
    vec![
        ("diffuse", Material::Diffuse(Diffuse::default())),
        (
            "phong",
            Material::Phong(Phong::new(40.0, Rgb::splat(0.5), Rgb::splat(0.3))),
        ),
        (
            "blinn_phong",
            Material::BlinnPhong(BlinnPhong::new(80.0, Rgb::splat(0.5), Rgb::splat(0.3))),
        ),
        (
            "gaussian",
            Material::Gaussian(Gaussian::new(0.2, Rgb::splat(0.5), Rgb::splat(0.3))),
        ),
        (
            "cook_torrance",
            Material::CookTorrance(CookTorrance {
                distribution: NormalDistribution::Analytic(Microfacet::isotropic(
                    Kind::Beckmann,
                    0.3,
                )),
                masking: Masking::VGroove,
                fresnel: Fresnel::Dielectric { ior: 1.5 },
                reflectance: Rgb::splat(0.4),
            }),
        ),
        (
            "beckmann",
            Material::Beckmann(Beckmann::new(0.2, 0.3, gold)),
        ),
        ("ggx", Material::Ggx(Ggx::new(0.2, 0.3, gold))),
        (
            "ward",
            Material::Ward(Ward::new(0.1, 0.3, Rgb::splat(0.5), Rgb::splat(0.3))),
        ),
        (
            "heidrich_seidel",
            Material::HeidrichSeidel(HeidrichSeidel::new(
                40.0,
                Rgb::splat(0.5),
                Rgb::splat(0.1),
                Rgb::splat(0.3),
            )),
        ),
        (
            "mix",
            Material::Mix(Mix {
                components: vec![
                    (Material::Diffuse(Diffuse::default()), 0.5),
                    (Material::Ggx(Ggx::new(0.2, 0.2, gold)), 0.5),
                ],
            }),
        ),
        (
            "conductor",
            Material::Conductor(Conductor { fresnel: gold }),
        ),
        ("dielectric", Material::Dielectric(Dielectric { ior: 1.5 })),
        (
            "plastic",
            Material::Plastic(Plastic::new(1.5, Rgb::splat(0.5), None)),
        ),
        (
            "rough_plastic",
            Material::Plastic(Plastic::new(1.5, Rgb::splat(0.5), Some(0.2))),
        ),
    ]
}

fn bench(c: &mut Criterion) {
    let mut rng = Pcg32::new(1, 1);
    let pairs: Vec<_> = (0..256)
        .map(|_| {
            let mut a = sampling::uniform_sphere(rng.next_2d());
            let mut b = sampling::uniform_sphere(rng.next_2d());
            a.z = a.z.abs();
            b.z = b.z.abs();
            (a, b, rng.next_f64(), rng.next_2d())
        })
        .collect();
    for (name, m) in models() {
        let mut i = 0usize;
        c.bench_function(&format!("eval/{name}"), |bch| {
            bch.iter(|| {
                let (wo, wi, _, _) = pairs[i & 255];
                i += 1;
                black_box(m.f(black_box(wo), black_box(wi)))
            })
        });
        let mut j = 0usize;
        c.bench_function(&format!("sample/{name}"), |bch| {
            bch.iter(|| {
                let (wo, _, uc, u) = pairs[j & 255];
                j += 1;
                black_box(m.sample(black_box(wo), uc, u))
            })
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
