"""The analytic aliasing model (addon/warp/aliasing.py) reproduces the papers' claims."""
import math

import numpy as np
import pytest

from addon.measure import footprint
from addon.warp import aliasing as al
import aliasing_model as model
from addon.warp.geometry import look_along, ortho_matrix
from addon.warp.types import ShadowMap, View

N, F, PHI = 1.0, 100.0, math.pi / 6          # GMNPR Fig. 6's configuration
RULES = (model.lambda_lispsm, al.lambda_gmnpr, al.lambda_glpr)


def _near_far_ratio(rule, theta, n=N, f=F, phi=PHI):
    lam = rule(theta, n, f, phi)
    return float(model.aliasing_F(lam, theta, n, n, f, phi) / model.aliasing_F(lam, theta, f, n, f, phi))


@pytest.mark.parametrize("theta_deg", [35.0, 40.0, 60.0, 75.0, 90.0])
@pytest.mark.parametrize("case", [("eq2", lambda z: z)])
def test_eq2_matches_the_geometric_definition_F_is_dz_over_z_ds(theta_deg, case):
    """Eq. 2's ψ, φ form equals (1/tan φ)·dz/(z ds) of the warp frustum's hyperbolic
    map coordinate s(z) (the computational model of GMNPR Fig. 4)."""
    theta = math.radians(theta_deg)
    for lam in (0.01, 0.3, 2.0):
        z = np.linspace(N, F, 7)
        h = 1e-6 * z
        ds = (model.map_coordinate(lam, theta, z + h, N, F, PHI) - model.map_coordinate(lam, theta, z - h, N, F, PHI)) / (2 * h)
        geometric = 1.0 / (math.tan(PHI) * z * ds)
        assert np.allclose(model.aliasing_F(lam, theta, z, N, F, PHI), geometric, rtol=1e-6)


def test_eq2_matches_the_geometric_definition_below_the_critical_angle():
    theta = math.radians(20.0)
    for lam in (0.05, 1.0):
        z = np.linspace(N, F, 7)
        h = 1e-6 * z
        ds = (model.map_coordinate(lam, theta, z + h, N, F, PHI) - model.map_coordinate(lam, theta, z - h, N, F, PHI)) / (2 * h)
        assert np.allclose(model.aliasing_F(lam, theta, z, N, F, PHI), 1.0 / (math.tan(PHI) * z * ds), rtol=1e-6)


def test_map_coordinate_spans_the_warp_frustum():
    for theta in (math.radians(20), math.radians(60), math.pi / 2):
        ext = model.model_extent(theta, N, F, PHI)
        near = model.model_near_side(theta, N, F, PHI)
        lam = 0.2
        # s = 0 at the frustum's near side, 1 at its far side
        d0 = (near - near) / ext + lam
        assert (1 + lam) * (1 - lam / d0) == pytest.approx(0.0, abs=1e-12)
        assert (1 + lam) * (1 - lam / (1 + lam)) == pytest.approx(1.0)


def test_model_extent_and_near_side_are_continuous_at_the_critical_angle():
    for fn in (model.model_extent, model.model_near_side):
        lo, hi = fn(PHI - 1e-12, N, F, PHI), fn(PHI + 1e-12, N, F, PHI)
        assert float(lo) == pytest.approx(float(hi), rel=1e-9, abs=1e-9)
    assert float(model.model_extent(PHI, N, F, PHI)) == pytest.approx(2 * F * math.sin(PHI))


@pytest.mark.parametrize("theta_deg", np.linspace(30.5, 90.0, 12))
def test_gmnpr_equalises_the_error_at_near_and_far_above_the_critical_angle(theta_deg):
    assert _near_far_ratio(al.lambda_gmnpr, math.radians(theta_deg)) == pytest.approx(1.0, rel=1e-9)


@pytest.mark.parametrize("n,f,phi", [(0.1, 70.0, math.radians(30)), (1.0, 800.0, math.pi / 6), (0.5, 20.0, math.radians(45))])
def test_gmnpr_equalises_for_other_frusta_too(n, f, phi):
    for theta in np.linspace(phi + 1e-6, math.pi / 2, 9):
        assert _near_far_ratio(al.lambda_gmnpr, theta, n, f, phi) == pytest.approx(1.0, rel=1e-9)


def test_lispsm_equalises_only_at_90_degrees():
    assert _near_far_ratio(model.lambda_lispsm, math.pi / 2) == pytest.approx(1.0, rel=1e-9)
    for theta_deg in (35.0, 45.0, 60.0, 75.0, 85.0):
        r = _near_far_ratio(model.lambda_lispsm, math.radians(theta_deg))
        assert abs(r - 1.0) > 0.02, theta_deg
    # and the disagreement grows as θ leaves the ideal case (GMNPR §3, Fig. 6)
    devs = [abs(_near_far_ratio(model.lambda_lispsm, math.radians(t)) - 1) for t in (85.0, 70.0, 50.0)]
    assert devs[0] < devs[1] < devs[2]


def test_lispsm_lambda_is_eq1_over_the_extent():
    for theta in (math.radians(20), math.radians(50), math.pi / 2):
        n_opt = (N + math.sqrt(N * F)) / math.sin(theta)
        assert model.lambda_lispsm(theta, N, F, PHI) == pytest.approx(n_opt / float(model.model_extent(theta, N, F, PHI)))
    # GMNPR Eq. 9 printed form, case θ ≥ φ
    theta = math.radians(60)
    t = math.tan(PHI) / math.tan(theta)
    eq9 = (N + math.sqrt(F * N)) / math.sin(theta) / ((N * t + F - N + F * t) * math.sin(theta))
    assert model.lambda_lispsm(theta, N, F, PHI) == pytest.approx(eq9)
    theta = math.radians(20)
    eq9 = (N + math.sqrt(F * N)) / math.sin(theta) / (2 * F * math.tan(PHI) * math.cos(theta))
    assert model.lambda_lispsm(theta, N, F, PHI) == pytest.approx(eq9)


def test_glpr_makes_F_linear_in_z():
    for theta_deg in (50.0, 70.0, 90.0):
        theta = math.radians(theta_deg)
        lam = al.lambda_glpr(theta, N, F, PHI)
        z = np.linspace(N, F, 9)
        f_over_z = model.aliasing_F(lam, theta, z, N, F, PHI) / z
        assert np.allclose(f_over_z, f_over_z[0], rtol=1e-9)
    assert al.lambda_glpr(math.pi / 2, N, F, PHI) == pytest.approx(N / (F - N))


@pytest.mark.parametrize("rule", RULES, ids=lambda r: r.__name__)
def test_every_warp_converges_to_uniform_as_theta_goes_to_zero(rule):
    z = np.linspace(N, F, 11)
    previous = math.inf
    for theta in (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
        lam = rule(theta, N, F, PHI)
        dev = float(np.max(np.abs(model.aliasing_F(lam, theta, z, N, F, PHI) / model.uniform_F(theta, z, N, F, PHI) - 1)))
        assert dev < previous
        previous = dev
    assert previous < 1e-3
    assert rule(0.0, N, F, PHI) == math.inf
    assert np.all(model.aliasing_F(math.inf, 0.3, z, N, F, PHI) == model.uniform_F(0.3, z, N, F, PHI))


@pytest.mark.parametrize("rule", RULES, ids=lambda r: r.__name__)
def test_lambda_rules_are_continuous_at_the_critical_angle(rule):
    at = rule(PHI, N, F, PHI)
    for eps in (1e-9, -1e-9):
        assert rule(PHI + eps, N, F, PHI) == pytest.approx(at, rel=1e-6)
    assert at > 0


def test_gmnpr_lambda_at_the_critical_angle_is_sqrt_fn_over_2f():
    assert al.lambda_gmnpr(PHI, N, F, PHI) == pytest.approx(math.sqrt(F * N) / (2 * F), rel=1e-12)
    below = al.lambda_gmnpr(PHI * (1 - 1e-12), N, F, PHI)
    assert below == pytest.approx(math.sqrt(F * N) / (2 * F), rel=1e-9)


def test_lispsm_inverse_n_opt_is_finite_and_zero_when_parallel():
    assert al.lispsm_inverse_n_opt(0.1, 69.9, 0.0) == 0.0
    assert al.lispsm_inverse_n_opt(0.1, 69.9, math.pi) == pytest.approx(0.0, abs=1e-15)
    assert 1 / al.lispsm_inverse_n_opt(0.1, 69.9, math.pi / 2) == pytest.approx(0.1 + math.sqrt(0.1 * 70.0))
    assert 1 / al.lispsm_inverse_n_opt(1.0, 99.0, math.radians(30)) == pytest.approx((1 + 10.0) / 0.5)


# ---------------------------------------------------------------- texel footprint

def _top_down_view(height, fov_y_deg, res):
    c2w = np.linalg.inv(look_along([0.0, 0.0, height], [0, 0, -1], [0, 1, 0]))
    return View.perspective(c2w, math.radians(fov_y_deg), res[0] / res[1], 0.1, 100.0, res)


def _sun_map(half_extent, size):
    w2l = look_along([0.0, 0.0, 50.0], [0, 0, -1], [0, 1, 0])
    return ShadowMap(ortho_matrix(-half_extent, half_extent, -half_extent, half_extent, 1.0, 100.0) @ w2l, size)


def test_top_down_sun_over_a_plane_with_a_uniform_map_has_a_constant_known_footprint():
    height, fov, res = 10.0, 60.0, (1280, 720)
    view = _top_down_view(height, fov, res)
    sm = _sun_map(20.0, (1024, 512))
    rng = np.random.default_rng(1)
    half_h = height * math.tan(math.radians(fov) / 2)
    pts = np.column_stack([rng.uniform(-half_h * 16 / 9, half_h * 16 / 9, 400), rng.uniform(-half_h, half_h, 400),
                           np.zeros(400)])
    normals = np.tile([0.0, 0.0, 1.0], (400, 1))
    pixel = 2 * half_h / res[1]                        # world length of a screen pixel on the plane
    texel_x, texel_y = 40.0 / 1024, 40.0 / 512
    lin = footprint.texel_footprint(view, sm, pts, normals)
    area = footprint.texel_footprint_area(view, sm, pts, normals)
    assert np.allclose(lin, max(texel_x, texel_y) / pixel, rtol=1e-9)
    assert np.allclose(area, texel_x * texel_y / pixel ** 2, rtol=1e-9)


def test_footprint_is_the_worst_direction_for_an_oblique_sun():
    view = _top_down_view(10.0, 60.0, (800, 800))
    # sun tilted 60 degrees from vertical about the y axis: the plane is stretched along x by 1/cos 60
    d = np.array([math.sin(math.radians(60)), 0.0, -math.cos(math.radians(60))])
    w2l = look_along([0.0, 0.0, 0.0] - 50 * d, d, [0, 1, 0])
    sm = ShadowMap(ortho_matrix(-10, 10, -10, 10, 1.0, 200.0) @ w2l, (1000, 1000))
    pts = np.array([[0.5, -1.0, 0.0], [2.0, 3.0, 0.0]])
    normals = np.tile([0.0, 0.0, 1.0], (2, 1))
    pixel = 2 * 10.0 * math.tan(math.radians(30)) / 800
    texel = 20.0 / 1000
    assert np.allclose(footprint.texel_footprint(view, sm, pts, normals), texel / math.cos(math.radians(60)) / pixel, rtol=1e-9)
    assert np.allclose(footprint.texel_footprint_area(view, sm, pts, normals),
                       texel ** 2 / math.cos(math.radians(60)) / pixel ** 2, rtol=1e-9)


def test_footprint_is_inf_edge_on_to_the_map_and_nan_behind_the_camera():
    view = _top_down_view(10.0, 60.0, (800, 800))
    sm = _sun_map(10.0, (512, 512))
    pts = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 20.0]])            # the second is behind the camera
    normals = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])         # the first is a wall parallel to the light
    fp = footprint.texel_footprint(view, sm, pts, normals)
    assert fp[0] == math.inf
    assert math.isnan(fp[1])


@pytest.mark.parametrize("theta_deg", [5.0, 20.0, 29.0, 31.0, 55.0, 90.0])
def test_eq2_at_near_and_far_matches_the_papers_case_values(theta_deg):
    """GMNPR §3's closed forms of F(λ, θ, n) and F(λ, θ, f) (Case 1 and Case 2)."""
    theta = math.radians(theta_deg)
    tp, tt = math.tan(PHI), math.tan(theta)
    for lam in (0.02, 0.7):
        if theta >= PHI:
            k = F - N + (F + N) * tp / tt
            mu = N / ((F - N) * tt / tp + F + N)
            nu = 1 - F / ((F - N) * tt / tp + F + N)
            fn = k / (N * tp) * (lam + mu) ** 2 / (lam * (lam + 1))
            ff = k / (F * tp) * (lam + nu) ** 2 / (lam * (lam + 1))
        else:
            mu = 0.5 - (F - N) / (2 * F) * tt / tp
            nu = 0.5
            fn = 2 * F / (N * tt) * (lam + mu) ** 2 / (lam * (lam + 1))
            ff = 2 / tt * (lam + nu) ** 2 / (lam * (lam + 1))
        assert float(model.aliasing_F(lam, theta, N, N, F, PHI)) == pytest.approx(fn, rel=1e-9)
        assert float(model.aliasing_F(lam, theta, F, N, F, PHI)) == pytest.approx(ff, rel=1e-9)


# ----------------------------------------------------------------------------- GLPR's guard

@pytest.mark.parametrize("n,f,phi", [(N, F, PHI), (1.0, 800.0, math.pi / 6), (128.0, 600.0, math.radians(25))])
def test_at_the_guard_the_warps_worst_aliasing_is_the_uniform_maps_worst(n, f, phi):
    """lambda_no_worse_than_uniform: over [n, f] the warp's largest F (GMNPR Eq. 2,
    at an end: F is convex in z) equals the uniform map's largest (at n); any
    stronger warp (smaller λ) is worse there."""
    z = np.geomspace(n, f, 2001)
    for theta in np.radians([2.0, 12.0, 25.0, 40.0, 65.0, 90.0]):
        lam = al.lambda_no_worse_than_uniform(theta, n, f, phi)
        worst_uniform = float(model.uniform_F(theta, n, n, f, phi))
        assert model.aliasing_F(lam, theta, z, n, f, phi).max() == pytest.approx(worst_uniform, rel=1e-9)
        assert model.aliasing_F(0.97 * lam, theta, z, n, f, phi).max() > worst_uniform * (1 + 1e-6)


def test_in_the_ideal_case_the_guard_is_glprs_own_lambda_and_below_it_glpr_over_warps():
    """θ = π/2: GLPR's far-end aliasing is exactly the uniform map's near-end one;
    at every other angle GLPR's λ is below the guard (GMNPR §3: 'over-strong')."""
    assert al.lambda_no_worse_than_uniform(math.pi / 2, N, F, PHI) == pytest.approx(al.lambda_glpr(math.pi / 2, N, F, PHI))
    for theta in np.radians([5.0, 20.0, 31.0, 45.0, 80.0]):
        assert al.lambda_glpr(theta, N, F, PHI) < al.lambda_no_worse_than_uniform(theta, N, F, PHI)


def test_gmnprs_minimax_lambda_meets_the_guard_above_the_critical_angle():
    for theta in np.radians([31.0, 45.0, 60.0, 89.0]):
        assert al.lambda_gmnpr(theta, N, F, PHI) >= al.lambda_no_worse_than_uniform(theta, N, F, PHI)


def test_the_average_guard_makes_the_l2_norm_of_the_texel_ratio_one():
    """lambda_no_worse_on_average: at the returned λ, E[ρ²] = 1 over the pixels
    (ρ = (λ + δ)²/(λ(λ + 1)), the warp's texel along V_P over the uniform map's);
    a stronger warp makes it worse, a weaker one better."""
    rng = np.random.default_rng(0)
    for a, b in ((1, 4), (2, 5), (1, 8), (0.5, 1.5)):
        delta = rng.beta(a, b, 4000)
        weights = rng.uniform(0.5, 2.0, 4000)
        lam = al.lambda_no_worse_on_average(delta, weights)

        def l2(x):
            rho = (x + delta) ** 2 / (x * (x + 1))
            return float(weights @ rho ** 2 / weights.sum())
        assert l2(lam) == pytest.approx(1.0, rel=1e-9)
        assert l2(0.9 * lam) > 1.0 > l2(1.1 * lam)


def test_no_warp_wins_when_most_pixels_are_far_along_v_p():
    assert al.lambda_no_worse_on_average(np.full(10, 0.6)) == math.inf
    assert al.lambda_no_worse_on_average(np.linspace(0.1, 1.0, 91)) == math.inf
    assert al.lambda_no_worse_on_average(np.zeros(10)) == 0.0        # all at B's near side: any warp helps


def test_across_v_p_the_guard_weighs_the_texels_longer_side():
    """Across V_P the warp's texel at δ is (1 + δ/λ)·range((q - q_eye)/(1 + δ/λ))/D (the warp's x' fitted to B's
    vertices; the uniform map's is range(q)/D, its texel along V_P 1/D on a square map); the guard also asks
    E[ρ²] <= 1 for the texel's longer side over the uniform map's. B narrower than long (a wedge from the warp's
    centre, q = ±(δ + λ₀)/10, or a narrow box): the longer side stays along V_P, the guard is the along-only one.
    B wider than long and as wide at its near side as at its far side (casters beside the eye): every warp widens
    the longer side, only the uniform map is no worse. In between, the guard asks a weaker warp than along V_P
    alone, at which the longer side's E[ρ²] is exactly 1."""
    rng = np.random.default_rng(1)
    delta, weights = rng.beta(1, 4, 4000), rng.uniform(0.5, 2.0, 4000)

    def body(near, far):                      # B's vertices (δ, (q - q_eye)/D): half-widths at its near and far sides
        return np.array([0.0, 0.0, 1.0, 1.0]), np.array([-near, near, -far, far])
    along_only = al.lambda_no_worse_on_average(delta, weights)
    for narrow_or_wedge in (body(0.001, 0.101), body(0.01, 0.01)):
        assert al.lambda_no_worse_on_average(delta, weights, narrow_or_wedge) == pytest.approx(along_only, rel=1e-12)
    assert al.lambda_no_worse_on_average(delta, weights, body(1.0, 1.0)) == math.inf
    b = body(0.6, 1.0)
    lam = al.lambda_no_worse_on_average(delta, weights, b)
    assert lam > 1.5 * along_only

    def longer_side(x):
        across = (1 + delta / x) * np.ptp(b[1] / (1 + b[0] / x))
        side = np.maximum(across, (x + delta) ** 2 / (x * (x + 1))) / np.ptp(b[1])
        return float(weights @ side ** 2 / weights.sum())
    assert longer_side(lam) == pytest.approx(1.0, rel=1e-9)
    assert longer_side(0.9 * lam) > 1.0 > longer_side(1.1 * lam)


def test_the_screen_guard_is_the_warp_whose_texels_are_least_on_screen():
    """lambda_least_on_screen: a texel at eye depth z spans ∝ 1/z pixels, so over the visible pixels the warp's mean
    texel on screen is E[ρ/z]·(the uniform map's texel) for ρ the texel's side along V_P over uniform's; the λ
    returned is its least (against a brute-force sweep). Near pixels close to the eye ask a strong warp, pixels
    all at one depth none (the uniform map), and at the least the mean is below the uniform map's E[1/z]."""
    rng = np.random.default_rng(2)
    for a, b, depth_range in ((1, 4, 20.0), (2, 5, 5.0), (1, 2, 50.0)):
        delta = rng.beta(a, b, 3000)
        weights = rng.uniform(0.5, 2.0, 3000)
        depth = 1.0 + depth_range * delta * rng.uniform(0.8, 1.2, 3000)
        lam = al.lambda_least_on_screen(delta, weights, depth)

        def on_screen(x):
            return float(weights @ ((x + delta) ** 2 / (x * (x + 1)) / depth))
        sweep = np.geomspace(1e-3, 1e3, 4001)
        assert on_screen(lam) <= min(on_screen(x) for x in sweep) * (1 + 1e-9)
        assert on_screen(lam) < float(weights @ (1.0 / depth))
    assert al.lambda_least_on_screen(rng.uniform(0, 1, 100), np.ones(100), np.full(100, 3.0)) > 100.0
