//! Contacts keep their overlap's structure from step to step (`shared::dem::collision::kept`), and a
//! large hull's contact with a plane wall its wall set (`overlap_half_space_kept`): that must
//! change no bytes. The box scene (I_P and Ab_3 bodies rained into a box of plane
//! walls, with friction and damping) is run with structures and sets kept and with every one
//! found again each step, and through a restart from its written state, which keeps none.

use shared::dem::io::state::{read_world, write_world};
use shared::dem::scenes::{box_scene, dissipative, soft};
use shared::dem::world::World;

fn state(w: &World) -> Vec<u8> {
    let mut out = Vec::new();
    write_world(w, &mut out).unwrap();
    out
}

#[test]
fn kept_structures_and_restarts_give_the_same_bytes() {
    // Under 20 g the bodies fall, collide and pile up in 0.12 s (9041 steps, 274 contacts at
    // most): contacts made, kept and broken.
    let scene = || {
        let mut w = box_scene(dissipative(soft()), 0.2);
        w.gravity *= 20.0;
        w
    };
    let (mut kept, mut fresh) = (scene(), scene());
    fresh.keep_structures = false;
    let steps = (0.12 / kept.dt).round() as u64;
    let mut restarted = None;
    let mut most = 0;
    for step in 1..=steps {
        kept.step();
        fresh.step();
        most = most.max(kept.contacts.len());
        if step % 100 == 0 || step == steps {
            assert_eq!(state(&kept), state(&fresh), "step {step}");
        }
        if step == steps / 2 {
            restarted = Some(read_world(&state(&kept)[..]).unwrap());
        }
        if let Some(r) = restarted.as_mut().filter(|_| step > steps / 2) {
            r.step();
        }
    }
    assert!(most > 200, "a pile forms: at most {most} contacts");
    assert_eq!(state(&restarted.unwrap()), state(&kept), "restart");
}
