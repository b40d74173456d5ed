//! The 16-, 8- and 4-point Gauss–Legendre rules on [−1, 1], by their
//! positive halves: the nodes ±x_k carry the weight w_k. The arc length
//! integrals of the host's geometry and of the pieces' fit use the same
//! rules (the shorter ones over short steps).

/// Positive nodes of the 16-point Gauss–Legendre rule.
pub const GL16_X: [f64; 8] = [
    0.095_012_509_837_637_44,
    0.281_603_550_779_258_9,
    0.458_016_777_657_227_4,
    0.617_876_244_402_643_7,
    0.755_404_408_355_003,
    0.865_631_202_387_831_8,
    0.944_575_023_073_232_6,
    0.989_400_934_991_649_9,
];

/// Their weights.
pub const GL16_W: [f64; 8] = [
    0.189_450_610_455_068_5,
    0.182_603_415_044_923_6,
    0.169_156_519_395_002_5,
    0.149_595_988_816_576_7,
    0.124_628_971_255_533_9,
    0.095_158_511_682_492_78,
    0.062_253_523_938_647_89,
    0.027_152_459_411_754_095,
];

/// Positive nodes of the 8-point Gauss–Legendre rule.
pub const GL8_X: [f64; 4] = [
    0.183_434_642_495_649_8,
    0.525_532_409_916_329,
    0.796_666_477_413_626_7,
    0.960_289_856_497_536_3,
];

/// Their weights.
pub const GL8_W: [f64; 4] = [
    0.362_683_783_378_362,
    0.313_706_645_877_887_3,
    0.222_381_034_453_374_5,
    0.101_228_536_290_376_3,
];

/// Positive nodes of the 4-point Gauss–Legendre rule.
pub const GL4_X: [f64; 2] = [0.339_981_043_584_856_3, 0.861_136_311_594_052_6];

/// Their weights.
pub const GL4_W: [f64; 2] = [0.652_145_154_862_546_1, 0.347_854_845_137_453_9];
