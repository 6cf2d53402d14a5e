//! The implicit time transformation behind a [`Scheme`]: its drivers on the
//! extended system of `N + 1` coordinates, and the table that names `N + 1`
//! for each `N`.
//!
//! Stable Rust cannot write the type `Adaptive<…, N, { N + 1 }>` for a
//! generic `N` (that needs `generic_const_exprs`), and a run-time `match N`
//! over the candidates would instantiate every arm for every size (each arm
//! a whole integrator, refused at compile time where `M ≠ N + 1`). So a
//! sealed trait, [`Extended`], implemented by a macro for `Dim<1>` …
//! `Dim<1024>` (see [`MAX_PROBLEM_N`]), names the extended driver type
//! with the literal `N + 1`; only the sizes a program uses are instantiated,
//! and for each only when its scheme is matched. The table costs about one
//! CPU second when the runtime is compiled (1024 small impls, measured on a
//! standalone copy: 0.06 s for 64). A larger compile-time size is a
//! compile error naming [`DynProblem`](super::DynProblem) and the drivers.

use super::scheme::{OnePoint, Scheme};
use super::support::MAX_PROBLEM_N;
use crate::dense::{Hermite, Node};
use crate::discrete::{Midpoint, Trapezoid};
use crate::error::Error;
use crate::galerkin::{Galerkin, GalerkinIntegrator, Quadrature};
use crate::integrator::{Integrator, Stats};
use crate::newton::NewtonOptions;
use crate::solution::Stepping;
use crate::state::State;
use crate::system::Lagrangian;
use crate::time_transform::{Adaptive, Curvature, TimeTransformed};

/// The transformed system in `s`.
type Tt<S, const N: usize> = TimeTransformed<S, Curvature, N>;

/// The adaptive driver around a one-point rule `R`.
type OnePointIn<S, R, const N: usize, const M: usize> = Adaptive<Integrator<Tt<S, N>, R, M>, S, Curvature, N, M>;

/// The adaptive driver around the Galerkin rule of degree `D`.
type GalerkinIn<S, const N: usize, const M: usize, const D: usize> =
    Adaptive<GalerkinIntegrator<Tt<S, N>, M, D, D>, S, Curvature, N, M>;

/// The implicit time-transformed driver of a [`Scheme::TimeTransformed`],
/// `N` physical and `M = N + 1` extended coordinates: one variant per
/// method in `s`.
// The variants are the drivers themselves, of their own sizes: one is
// built per run and never moved in the stepping loop, and a box would add
// an indirection to every step.
#[allow(clippy::large_enum_variant)]
#[derive(Clone)]
pub enum Transformed<S, const N: usize, const M: usize> {
    /// Midpoint in `s`.
    Midpoint(OnePointIn<S, Midpoint, N, M>),
    /// Trapezoid in `s`.
    Trapezoid(OnePointIn<S, Trapezoid, N, M>),
    /// α-β in `s`.
    AlphaBeta(OnePointIn<S, crate::discrete::AlphaBeta, N, M>),
    /// Galerkin s = 2 in `s`.
    Galerkin2(GalerkinIn<S, N, M, 2>),
    /// Galerkin s = 3 in `s`.
    Galerkin3(GalerkinIn<S, N, M, 3>),
    /// Galerkin s = 4 in `s`.
    Galerkin4(GalerkinIn<S, N, M, 4>),
}

/// Runs `$body` with `$d` bound to the driver of whichever variant `$x` is.
macro_rules! each {
    ($x:expr, $d:ident => $body:expr) => {
        match $x {
            Transformed::Midpoint($d) => $body,
            Transformed::Trapezoid($d) => $body,
            Transformed::AlphaBeta($d) => $body,
            Transformed::Galerkin2($d) => $body,
            Transformed::Galerkin3($d) => $body,
            Transformed::Galerkin4($d) => $body,
        }
    };
}

impl<S: Lagrangian<N>, const N: usize, const M: usize> Transformed<S, N, M> {
    /// Starts the driver of `inner` in `s` (the schemes
    /// [`supports`](super::supports) accepts around a time transformation).
    #[allow(clippy::too_many_arguments)]
    fn start(
        system: S,
        inner: &Scheme,
        density: Curvature,
        sigma: f64,
        newton: Option<NewtonOptions>,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Result<Self, Error<N>> {
        let tt = TimeTransformed::new(system, density);
        macro_rules! go {
            ($builder:expr, $variant:ident) => {{
                let b = $builder;
                let b = match newton {
                    Some(o) => b.newton(o),
                    None => b,
                };
                b.start::<M>(t0, q0, v0).map(Transformed::$variant)
            }};
        }
        match inner {
            Scheme::OnePoint(OnePoint::Midpoint) => go!(tt.rule(Midpoint, sigma), Midpoint),
            Scheme::OnePoint(OnePoint::Trapezoid) => go!(tt.rule(Trapezoid, sigma), Trapezoid),
            Scheme::OnePoint(OnePoint::AlphaBeta(m)) => go!(tt.rule(*m, sigma), AlphaBeta),
            Scheme::Galerkin { degree: 2, nodes, .. } => {
                go!(tt.galerkin(Galerkin::<2, 2>::new(*nodes, Quadrature::gauss_legendre()), sigma), Galerkin2)
            }
            Scheme::Galerkin { degree: 3, nodes, .. } => {
                go!(tt.galerkin(Galerkin::<3, 3>::new(*nodes, Quadrature::gauss_legendre()), sigma), Galerkin3)
            }
            Scheme::Galerkin { degree: 4, nodes, .. } => {
                go!(tt.galerkin(Galerkin::<4, 4>::new(*nodes, Quadrature::gauss_legendre()), sigma), Galerkin4)
            }
            _ => Err(Error::Unsupported { what: "this method in `s` under the time transformation" }),
        }
    }
}

/// Every variant through the one stepper trait; dense output by the cubic
/// Hermite in physical time, as each driver's own.
impl<S: Lagrangian<N>, const N: usize, const M: usize> Stepping<N> for Transformed<S, N, M> {
    type System = S;
    type Native = Hermite<N>;

    fn system(&self) -> &S {
        each!(self, d => Stepping::system(d))
    }

    fn state(&self) -> State<N> {
        each!(self, d => Stepping::state(d))
    }

    fn velocity(&self) -> Result<[f64; N], Error<N>> {
        each!(self, d => Stepping::velocity(d))
    }

    fn stats(&self) -> Stats {
        each!(self, d => Stepping::stats(d))
    }

    fn step(&mut self) -> Result<(), Error<N>> {
        each!(self, d => Stepping::step(d))
    }

    fn step_toward(&mut self, t_end: f64, last_h: Option<f64>) -> Result<(), Error<N>> {
        each!(self, d => Stepping::step_toward(d, t_end, last_h))
    }

    fn land(&mut self, t: f64) -> Result<(), Error<N>> {
        each!(self, d => Stepping::land(d, t))
    }

    fn native(&self, start: &Node<N>, end: &Node<N>) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

/// `N`, as a type that can name `N + 1` (see [`Extended`]).
#[derive(Clone, Copy, Debug)]
pub struct Dim<const N: usize>;

mod sealed {
    /// Implemented only by the table of [`Dim`](super::Dim).
    pub trait Sealed {}
}

/// The sizes `N` (1 to [`MAX_PROBLEM_N`]) a [`Problem`](super::Problem)
/// can step: for each, the extended system of `N + 1` coordinates of a
/// [`Scheme::TimeTransformed`]. Sealed and implemented for every such
/// `Dim<N>`, so a program with a literal size never names it.
#[diagnostic::on_unimplemented(
    message = "`Problem` steps compile-time sizes up to 1024, not {N}",
    note = "use `DynProblem` (run-time size) or a driver (`Integrator`, `TimeTransformed`) directly"
)]
pub trait Extended<const N: usize>: sealed::Sealed {
    /// The driver, with `M = N + 1`.
    #[doc(hidden)]
    type Transformed<S: Lagrangian<N> + Clone>: Stepping<N, System = S, Native = Hermite<N>> + Clone;

    /// Starts it.
    #[doc(hidden)]
    #[allow(clippy::too_many_arguments)]
    fn start<S: Lagrangian<N> + Clone>(
        system: S,
        inner: &Scheme,
        density: Curvature,
        sigma: f64,
        newton: Option<NewtonOptions>,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Result<Self::Transformed<S>, Error<N>>;
}

/// The table: `impl Extended<n> for Dim<n>` with `M = n + 1`.
macro_rules! table {
    ($($n:literal)*) => {$(
        impl sealed::Sealed for Dim<$n> {}
        impl Extended<$n> for Dim<$n> {
            type Transformed<S: Lagrangian<$n> + Clone> = Transformed<S, $n, { $n + 1 }>;
            fn start<S: Lagrangian<$n> + Clone>(
                system: S,
                inner: &Scheme,
                density: Curvature,
                sigma: f64,
                newton: Option<NewtonOptions>,
                t0: f64,
                q0: [f64; $n],
                v0: [f64; $n],
            ) -> Result<Self::Transformed<S>, Error<$n>> {
                Transformed::start(system, inner, density, sigma, newton, t0, q0, v0)
            }
        }
    )*};
}

table!(
    1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32
    33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53 54 55 56 57 58 59 60 61 62 63 64
    65 66 67 68 69 70 71 72 73 74 75 76 77 78 79 80 81 82 83 84 85 86 87 88 89 90 91 92 93 94 95 96
    97 98 99 100 101 102 103 104 105 106 107 108 109 110 111 112 113 114 115 116 117 118 119 120 121 122 123 124 125 126 127 128
    129 130 131 132 133 134 135 136 137 138 139 140 141 142 143 144 145 146 147 148 149 150 151 152 153 154 155 156 157 158 159 160
    161 162 163 164 165 166 167 168 169 170 171 172 173 174 175 176 177 178 179 180 181 182 183 184 185 186 187 188 189 190 191 192
    193 194 195 196 197 198 199 200 201 202 203 204 205 206 207 208 209 210 211 212 213 214 215 216 217 218 219 220 221 222 223 224
    225 226 227 228 229 230 231 232 233 234 235 236 237 238 239 240 241 242 243 244 245 246 247 248 249 250 251 252 253 254 255 256
    257 258 259 260 261 262 263 264 265 266 267 268 269 270 271 272 273 274 275 276 277 278 279 280 281 282 283 284 285 286 287 288
    289 290 291 292 293 294 295 296 297 298 299 300 301 302 303 304 305 306 307 308 309 310 311 312 313 314 315 316 317 318 319 320
    321 322 323 324 325 326 327 328 329 330 331 332 333 334 335 336 337 338 339 340 341 342 343 344 345 346 347 348 349 350 351 352
    353 354 355 356 357 358 359 360 361 362 363 364 365 366 367 368 369 370 371 372 373 374 375 376 377 378 379 380 381 382 383 384
    385 386 387 388 389 390 391 392 393 394 395 396 397 398 399 400 401 402 403 404 405 406 407 408 409 410 411 412 413 414 415 416
    417 418 419 420 421 422 423 424 425 426 427 428 429 430 431 432 433 434 435 436 437 438 439 440 441 442 443 444 445 446 447 448
    449 450 451 452 453 454 455 456 457 458 459 460 461 462 463 464 465 466 467 468 469 470 471 472 473 474 475 476 477 478 479 480
    481 482 483 484 485 486 487 488 489 490 491 492 493 494 495 496 497 498 499 500 501 502 503 504 505 506 507 508 509 510 511 512
    513 514 515 516 517 518 519 520 521 522 523 524 525 526 527 528 529 530 531 532 533 534 535 536 537 538 539 540 541 542 543 544
    545 546 547 548 549 550 551 552 553 554 555 556 557 558 559 560 561 562 563 564 565 566 567 568 569 570 571 572 573 574 575 576
    577 578 579 580 581 582 583 584 585 586 587 588 589 590 591 592 593 594 595 596 597 598 599 600 601 602 603 604 605 606 607 608
    609 610 611 612 613 614 615 616 617 618 619 620 621 622 623 624 625 626 627 628 629 630 631 632 633 634 635 636 637 638 639 640
    641 642 643 644 645 646 647 648 649 650 651 652 653 654 655 656 657 658 659 660 661 662 663 664 665 666 667 668 669 670 671 672
    673 674 675 676 677 678 679 680 681 682 683 684 685 686 687 688 689 690 691 692 693 694 695 696 697 698 699 700 701 702 703 704
    705 706 707 708 709 710 711 712 713 714 715 716 717 718 719 720 721 722 723 724 725 726 727 728 729 730 731 732 733 734 735 736
    737 738 739 740 741 742 743 744 745 746 747 748 749 750 751 752 753 754 755 756 757 758 759 760 761 762 763 764 765 766 767 768
    769 770 771 772 773 774 775 776 777 778 779 780 781 782 783 784 785 786 787 788 789 790 791 792 793 794 795 796 797 798 799 800
    801 802 803 804 805 806 807 808 809 810 811 812 813 814 815 816 817 818 819 820 821 822 823 824 825 826 827 828 829 830 831 832
    833 834 835 836 837 838 839 840 841 842 843 844 845 846 847 848 849 850 851 852 853 854 855 856 857 858 859 860 861 862 863 864
    865 866 867 868 869 870 871 872 873 874 875 876 877 878 879 880 881 882 883 884 885 886 887 888 889 890 891 892 893 894 895 896
    897 898 899 900 901 902 903 904 905 906 907 908 909 910 911 912 913 914 915 916 917 918 919 920 921 922 923 924 925 926 927 928
    929 930 931 932 933 934 935 936 937 938 939 940 941 942 943 944 945 946 947 948 949 950 951 952 953 954 955 956 957 958 959 960
    961 962 963 964 965 966 967 968 969 970 971 972 973 974 975 976 977 978 979 980 981 982 983 984 985 986 987 988 989 990 991 992
    993 994 995 996 997 998 999 1000 1001 1002 1003 1004 1005 1006 1007 1008 1009 1010 1011 1012 1013 1014 1015 1016 1017 1018 1019 1020 1021 1022 1023 1024
);

const _: () = assert!(MAX_PROBLEM_N == 1024, "the table lists every size up to MAX_PROBLEM_N");
