// Notation of mechanism_sim's core, after the seed lecture (shared/seed, lecture 50,
// following appendix 8.3.2 of "Multibody Dynamics (1)", Corona Publishing).
//
// | code        | seed            | meaning                                                        |
// |-------------|-----------------|----------------------------------------------------------------|
// | r_i         | r^i             | position of body i's reference point (its centre of mass), O   |
// | p_i         | p^i             | unit Euler parameters (w, x, y, z) of body i                   |
// | A_Oi        | A^{Oi}          | rotation matrix, body-i components -> global components        |
// | A_ij        | A^{ij}          | (A_Oi)^T A_Oj                                                  |
// | v_i         | r_dot^i         | velocity of r_i, global components                             |
// | w_i         | omega'^i        | angular velocity of body i, body-i components                  |
// | dtheta_i    | delta theta'^Oi | virtual rotation of body i, body-i components                  |
// | sp_iB       | s'^B_i          | joint point B_i on body i, body-i components                   |
// | bxp_i ..    | b'^i_x ..       | joint frame unit vectors fixed in body i, body-i components    |
// | bx_i ..     | b^i_x ..        | the same in global components (A_Oi * bxp_i)                   |
// | d_ij        | d^{ij}          | B_i -> B_j = r_j + A_Oj sp_jB - r_i - A_Oi sp_iB               |
// | tilde(a)    | a~              | skew matrix, tilde(a) * b = a x b                              |
// | Phi         | C               | constraint violation (position level)                          |
// | Phi_q       | dC/d(r, theta') | constraint Jacobian: the coefficients of the variation delta C |
// | gamma       |                 | acceleration right-hand side: Phi_q * a = gamma                |
// | lambda      | lambda          | Lagrange multipliers; reaction generalized force = -Phi_q^T lambda |
// | alpha       | alpha           | screw lead per radian                                          |
// | phi         | phi             | rotation of body j relative to body i about bz_i               |
//
// Generalized coordinates of a body are (r_i, p_i); its velocity and variation
// coordinates are (v_i, w_i) and (delta r_i, dtheta_i): six per body, in that order.
// A Jacobian row of a two-body constraint is 12 wide: [r_i, theta'_i, r_j, theta'_j].
//
// Accelerations a = (v_dot, w_dot). For any constraint Phi(q) = 0,
//   Phi_ddot = Phi_q a + (d/dt Phi_q) v  =>  Phi_q a = gamma,  gamma = -(d/dt Phi_q) v.
// Each quantity carries its "centripetal" part: for a body-fixed vector a = A_Oi a',
//   a_dot = A_Oi (w x a'),  a_ddot = A_Oi (w_dot x a') + A_Oi (w x (w x a')),
// and the second term (a_cen) is what enters gamma.
#pragma once
