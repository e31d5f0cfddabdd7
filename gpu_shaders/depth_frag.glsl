/* Depth pass fragment stage for linear z (Scherzer §4.2): the window depth
 * u_depth_row . [world, 1], interpolated perspective-correctly (exact: it is
 * affine in the world position). The matrix's own z / w still clips.
 * Writing gl_FragDepth moves the depth test after the shader. Conservative
 * depth (layout(depth_greater), depth_write("GREATER")) does not bring it
 * back on Mesa's llvmpipe: its fragment pipeline tests late whenever the
 * shader writes depth (lp_state_fs.c), and a depth_greater variant measured
 * no faster (1M triangles, 2048²: 1.06 x a bare draw against 0.97 x for
 * this one, interleaved). So this stage does the least it can: one varying,
 * one clamp (bench/depth_pass.py: at most 1.2 x a bare draw). */
void main()
{
  gl_FragDepth = clamp(v_depth, 0.0, 1.0);
}
