//! numpy's `default_rng` in Rust, so a bench synthesises exactly the peer's noisy inputs.

/// numpy's `default_rng(seed)`: the seed goes through `SeedSequence` into a PCG64 (XSL-RR 128/64)
/// generator; `uniform` and `standard_normal` are numpy's (53-bit doubles, 256-layer ziggurat).
pub struct NumpyRng {
    state: u128,
    inc: u128,
    /// Ziggurat tables `ki`, `wi`, `fi` (Marsaglia & Tsang's recurrence with numpy's `r` and layer area).
    ki: [u64; 256],
    wi: [f64; 256],
    fi: [f64; 256],
}

impl NumpyRng {
    const MULT: u128 = (2_549_297_995_355_413_924u128 << 64) | 4_865_540_595_714_422_341;
    const ZIG_R: f64 = 3.654_152_885_361_009;

    pub fn new(seed: u32) -> Self {
        // SeedSequence(seed): hash the entropy into a pool of four words, then generate_state(4, uint64).
        let hashmix = |v: u32, h: &mut u32| {
            let mut v = v ^ *h;
            *h = h.wrapping_mul(0x931e_8875);
            v = v.wrapping_mul(*h);
            v ^ (v >> 16)
        };
        let mix = |x: u32, y: u32| {
            let r = 0xca01_f9ddu32.wrapping_mul(x).wrapping_sub(0x4973_f715u32.wrapping_mul(y));
            r ^ (r >> 16)
        };
        let mut h = 0x43b0_d7e5u32;
        let mut pool = [0u32; 4];
        for (i, p) in pool.iter_mut().enumerate() {
            *p = hashmix(if i == 0 { seed } else { 0 }, &mut h);
        }
        for src in 0..4 {
            for dst in 0..4 {
                if src != dst {
                    pool[dst] = mix(pool[dst], hashmix(pool[src], &mut h));
                }
            }
        }
        let mut hb = 0x8b51_f9ddu32;
        let mut word = |i: usize| {
            let mut v = pool[i % 4] ^ hb;
            hb = hb.wrapping_mul(0x58f3_8ded);
            v = v.wrapping_mul(hb);
            u64::from(v ^ (v >> 16))
        };
        let words: Vec<u64> = (0..4).map(|i| word(2 * i) | (word(2 * i + 1) << 32)).collect();
        let init_state = (u128::from(words[0]) << 64) | u128::from(words[1]);
        let init_seq = (u128::from(words[2]) << 64) | u128::from(words[3]);
        // Ziggurat tables; the layer area is the one of numpy's wi[0].
        let (r, m1) = (Self::ZIG_R, 2f64.powi(52));
        let tail = (-0.5 * r * r).exp();
        let area = 8.683_627_060_801_306e-16 * m1 * tail;
        let (mut ki, mut wi, mut fi) = ([0u64; 256], [0f64; 256], [0f64; 256]);
        let q = area / tail;
        ki[0] = (r / q * m1) as u64;
        wi[0] = q / m1;
        wi[255] = r / m1;
        fi[0] = 1.0;
        fi[255] = tail;
        let (mut dn, mut tn) = (r, r);
        for i in (1..255).rev() {
            dn = (-2.0 * (area / dn + (-0.5 * dn * dn).exp()).ln()).sqrt();
            ki[i + 1] = (dn / tn * m1) as u64;
            tn = dn;
            fi[i] = (-0.5 * dn * dn).exp();
            wi[i] = dn / m1;
        }
        let mut rng = NumpyRng { state: 0, inc: (init_seq << 1) | 1, ki, wi, fi };
        rng.next_u64();
        rng.state = rng.state.wrapping_add(init_state);
        rng.next_u64();
        rng
    }

    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_mul(Self::MULT).wrapping_add(self.inc);
        (((self.state >> 64) as u64) ^ (self.state as u64)).rotate_right((self.state >> 122) as u32)
    }

    /// `random()`: 53-bit double in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }

    /// `uniform(low, high)`.
    pub fn uniform(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.next_f64()
    }

    /// `standard_normal()`: numpy's ziggurat.
    pub fn normal(&mut self) -> f64 {
        loop {
            let r = self.next_u64();
            let idx = (r & 0xff) as usize;
            let r = r >> 8;
            let rabs = (r >> 1) & 0x000f_ffff_ffff_ffff;
            let x = if r & 1 == 1 { -(rabs as f64 * self.wi[idx]) } else { rabs as f64 * self.wi[idx] };
            if rabs < self.ki[idx] {
                return x;
            }
            if idx == 0 {
                loop {
                    let xx = -(1.0 / Self::ZIG_R) * (-self.next_f64()).ln_1p();
                    let yy = -(-self.next_f64()).ln_1p();
                    if yy + yy > xx * xx {
                        return if (rabs >> 8) & 1 == 1 { -(Self::ZIG_R + xx) } else { Self::ZIG_R + xx };
                    }
                }
            } else if (self.fi[idx - 1] - self.fi[idx]) * self.next_f64() + self.fi[idx] < (-0.5 * x * x).exp() {
                return x;
            }
        }
    }
}
