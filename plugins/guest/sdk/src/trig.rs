//! Sine and cosine in pairs. FFT planners (rustfft, realfft) take each twiddle factor's
//! cosine and then its sine of the same angle, and WebAssembly has no instruction for
//! either: the standard library's `sin` and `cos` are software (libm), each reducing its
//! argument to `[-π/4, π/4]` apart. [`Pair`] computes both with one reduction
//! (`libm::sincos`) at the first call for an angle and answers the second from memory.
//! The values are libm's own `sin` and `cos`, bit for bit: `sincos` runs the same reduction
//! and the same kernels.

/// The sine and cosine of the last angle asked for.
pub struct Pair {
    /// The angle's bits (a NaN's before the first call, whose sine and cosine are NaN).
    angle: u64,
    sin: f64,
    cos: f64,
}

impl Pair {
    pub const fn new() -> Pair {
        Pair { angle: f64::NAN.to_bits(), sin: f64::NAN, cos: f64::NAN }
    }

    /// `sin x`, as `libm::sin`.
    #[inline]
    pub fn sin(&mut self, x: f64) -> f64 {
        self.at(x);
        self.sin
    }

    /// `cos x`, as `libm::cos`.
    #[inline]
    pub fn cos(&mut self, x: f64) -> f64 {
        self.at(x);
        self.cos
    }

    /// The memory's test alone, small enough for the host's compiler to inline at each call.
    #[inline]
    fn at(&mut self, x: f64) {
        if x.to_bits() != self.angle {
            self.reduce(x);
        }
    }

    #[inline(never)]
    fn reduce(&mut self, x: f64) {
        (self.sin, self.cos) = libm::sincos(x);
        self.angle = x.to_bits();
    }
}

impl Default for Pair {
    fn default() -> Pair {
        Pair::new()
    }
}
